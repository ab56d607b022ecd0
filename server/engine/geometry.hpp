// The engine's short name for protocol/cpp/geometry.hpp (Vec3, Int3, Box), which the protocol shares.
#pragma once

#include "protocol/cpp/geometry.hpp"
