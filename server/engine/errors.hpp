// The engine's error type (protocol/cpp/errors.hpp) and its precondition helpers. Every public entry
// point validates its parameters before it touches a volume.
#pragma once

#include "protocol/cpp/errors.hpp"

namespace marzipan {

// Precondition helpers: each names the parameter and says what a valid value looks like.
void requireFinite(double v, const char* field);
void requirePositive(double v, const char* field);
void requireRange(double v, double lo, double hi, const char* field);

}  // namespace marzipan
