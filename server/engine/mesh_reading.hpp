// What the mesh parsers (stl, obj, ply) and mesh_to_volume share, internal to the engine: the
// Format error, welding of vertices at identical positions, and line and token scanning of text
// formats. Conventions in mesh_format.hpp.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace marzipan::mesh_reading {

// EngineError(ErrorKind::Format, "mesh", what), with "line N: " in front for lineError.
[[noreturn]] void formatError(const std::string& what);
[[noreturn]] void lineError(std::size_t line, const std::string& what);

// Throws when a file describes more than kMaxMeshTriangles triangles.
void checkTriangleCount(std::size_t n);

// Merges vertices at bit-identical positions (0 and -0 alike), in order of first use.
class Welder {
 public:
  // The index of the vertex at (x, y, z), added to `positions` the first time it is seen.
  std::uint32_t add(float x, float y, float z) {
    const Key k{bits(x), bits(y), bits(z)};
    const auto [it, fresh] = index_.try_emplace(k, std::uint32_t(positions.size() / 3));
    if (fresh) positions.insert(positions.end(), {x, y, z});
    return it->second;
  }
  std::vector<float> positions;

 private:
  struct Key {
    std::uint32_t x, y, z;
    friend bool operator==(const Key&, const Key&) = default;
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
      h = (h ^ k.y) * 0xC2B2AE3D27D4EB4Full;
      h = (h ^ k.z) * 0x165667B19E3779F9ull;
      return std::size_t(h ^ (h >> 32));
    }
  };
  static std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f == 0 ? 0.0f : f); }
  std::unordered_map<Key, std::uint32_t, Hash> index_;
};

// The lines of a text, '\n' or "\r\n" ended, counted from 1.
struct Lines {
  std::string_view text;
  std::size_t pos = 0, number = 0;

  bool next(std::string_view& line) {
    if (pos >= text.size()) return false;
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    line = text.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    ++number;
    return true;
  }
};

// Blanks within a line (no '\n').
inline bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// Splits off the next whitespace-separated token; empty at the end of the line.
std::string_view token(std::string_view& s);

// A float written in full ("+" allowed in front); false when t is anything else.
bool parseFloat(std::string_view t, float& out);
// A finite coordinate, or a lineError saying what was found instead.
float coordinate(std::string_view t, std::size_t line);

}  // namespace marzipan::mesh_reading
