// The engine's error type (common/errors.hpp) and its precondition helpers. Every public entry
// point validates its parameters before it touches a volume.
#pragma once

#include "common/errors.hpp"

namespace marzipan {

// Precondition helpers: each names the parameter and says what a valid value looks like.
void requireFinite(double v, const char* field);
void requirePositive(double v, const char* field);
void requireRange(double v, double lo, double hi, const char* field);

}  // namespace marzipan
