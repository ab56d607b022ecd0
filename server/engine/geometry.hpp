// The engine's short name for common/geometry.hpp (Vec3, Int3, Box), which the protocol shares.
#pragma once

#include "common/geometry.hpp"
