// sRGB colour bytes (channels.hpp) to and from linear light, for the files that define their
// colours as linear: glTF's COLOR_0 (gltf.hpp) and the .vdb colour grid (openvdb/vdb_io.hpp).
//
// Conventions: the sRGB transfer function of IEC 61966-2-1 (a linear toe below 0.04045, a 2.4
// power above); linear values in [0, 1]. Encoding the linear value of a byte and rounding gives
// the byte again, for each of the 256 (tests/engine/test_gltf.cpp), so a float file holds a
// painted colour exactly.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace marzipan {

inline float srgbToLinear(std::uint8_t c) {
  const double v = c / 255.0;
  return float(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
}

// The sRGB byte of a linear value, clamped to [0, 1] first; v must not be NaN.
inline std::uint8_t linearToSrgb(double v) {
  v = std::clamp(v, 0.0, 1.0);
  const double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
  return std::uint8_t(std::lround(255 * s));
}

}  // namespace marzipan
