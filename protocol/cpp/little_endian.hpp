// Little-endian reads and writes of unaligned integers and floats: every binary format of
// Marzipan (frames, splats, .mzv volume files, STL/PLY meshes) is little-endian whatever the host.
// Standard library only, so that the protocol and the engine can share it.
#pragma once

#include <bit>
#include <cstdint>
#include <vector>

namespace marzipan::le {

inline void put16(std::uint8_t* p, std::uint32_t v) {
  p[0] = std::uint8_t(v);
  p[1] = std::uint8_t(v >> 8);
}
inline void put32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = std::uint8_t(v >> (8 * i));
}
inline void put64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = std::uint8_t(v >> (8 * i));
}
inline std::uint32_t get16(const std::uint8_t* p) { return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8; }
inline std::uint32_t get32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
inline std::uint64_t get64(const std::uint8_t* p) { return std::uint64_t(get32(p)) | std::uint64_t(get32(p + 4)) << 32; }
inline float getF32(const std::uint8_t* p) { return std::bit_cast<float>(get32(p)); }

inline void append32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(v >> (8 * i)));
}
inline void appendF32(std::vector<std::uint8_t>& out, float f) { append32(out, std::bit_cast<std::uint32_t>(f)); }

}  // namespace marzipan::le
