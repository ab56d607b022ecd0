#include "stl.hpp"

#include <cmath>
#include <cstring>

#include "little_endian.hpp"
#include "mesh_reading.hpp"

namespace marzipan {

using namespace mesh_reading;
using le::append32;
using le::appendF32;
using le::get32;
using le::getF32;

namespace {

Mesh parseBinaryStl(std::span<const std::uint8_t> bytes, std::uint32_t count) {
  checkTriangleCount(count);
  Welder w;
  Mesh m;
  m.indices.reserve(std::size_t(count) * 3);
  for (std::size_t t = 0; t < count; ++t) {
    const std::uint8_t* p = bytes.data() + 84 + 50 * t + 12;
    for (int k = 0; k < 3; ++k, p += 12) {
      const float x = getF32(p), y = getF32(p + 4), z = getF32(p + 8);
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        formatError("triangle " + std::to_string(t) + ": coordinate is not finite");
      m.indices.push_back(w.add(x, y, z));
    }
  }
  m.positions = std::move(w.positions);
  return m;
}

Mesh parseAsciiStl(std::string_view text) {
  Lines lines{text};
  std::string_view line;
  Welder w;
  Mesh m;
  enum class State { Start, Solid, Facet, Loop, EndLoop, End };
  State state = State::Start;
  int corners = 0;
  auto expect = [&](std::string_view& rest, std::string_view word) {
    if (token(rest) != word) lineError(lines.number, "expected \"" + std::string(word) + "\"");
  };
  while (lines.next(line)) {
    std::string_view rest = line;
    const std::string_view kw = token(rest);
    if (kw.empty()) continue;
    switch (state) {
      case State::Start:
      case State::End:
        if (kw != "solid") lineError(lines.number, "expected \"solid\"");
        state = State::Solid;
        continue;  // the solid's name is free text
      case State::Solid:
        if (kw == "endsolid") {
          state = State::End;
          continue;
        }
        if (kw != "facet") lineError(lines.number, "expected \"facet\" or \"endsolid\"");
        state = State::Facet;
        break;
      case State::Facet:
        if (kw != "outer") lineError(lines.number, "expected \"outer loop\"");
        expect(rest, "loop");
        state = State::Loop;
        corners = 0;
        break;
      case State::Loop:
        if (kw == "endloop") {
          if (corners != 3) lineError(lines.number, "a facet needs exactly 3 vertices");
          state = State::EndLoop;
          break;
        }
        if (kw != "vertex") lineError(lines.number, "expected \"vertex\"");
        if (++corners > 3) lineError(lines.number, "a facet needs exactly 3 vertices");
        {
          const float x = coordinate(token(rest), lines.number);
          const float y = coordinate(token(rest), lines.number);
          const float z = coordinate(token(rest), lines.number);
          m.indices.push_back(w.add(x, y, z));
        }
        break;
      case State::EndLoop:
        if (kw != "endfacet") lineError(lines.number, "expected \"endfacet\"");
        checkTriangleCount(m.indices.size() / 3);
        state = State::Solid;
        break;
    }
  }
  if (state != State::End) formatError("ASCII STL ends before \"endsolid\"");
  m.positions = std::move(w.positions);
  return m;
}

}  // namespace

std::vector<std::uint8_t> exportStl(const Mesh& m) {
  requireExportable(m);
  std::vector<std::uint8_t> out(80, 0);
  const char header[] = "Marzipan binary STL";
  std::memcpy(out.data(), header, sizeof header - 1);
  out.reserve(84 + 50 * m.triangleCount());
  append32(out, std::uint32_t(m.triangleCount()));
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const std::uint32_t* i = &m.indices[3 * t];
    const Vec3 a = m.position(i[0]), b = m.position(i[1]), c = m.position(i[2]);
    const Vec3 n = normalized(cross(b - a, c - a));
    appendF32(out, float(n.x)), appendF32(out, float(n.y)), appendF32(out, float(n.z));
    for (int k = 0; k < 3; ++k)
      for (int a2 = 0; a2 < 3; ++a2) appendF32(out, m.positions[3 * std::size_t(i[k]) + std::size_t(a2)]);
    out.push_back(0), out.push_back(0);
  }
  return out;
}

Mesh parseStl(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) formatError("STL is empty");
  if (bytes.size() >= 84) {
    const std::uint32_t count = get32(bytes.data() + 80);
    if (std::uint64_t(bytes.size()) == 84 + 50 * std::uint64_t(count)) {
      if (count == 0) formatError("STL has no triangles");
      return parseBinaryStl(bytes, count);
    }
  }
  std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  std::size_t i = 0;
  while (i < text.size() && (isSpace(text[i]) || text[i] == '\n')) ++i;
  if (text.substr(i, 5) == "solid" && text.find('\0') == std::string_view::npos) {
    Mesh m = parseAsciiStl(text);
    if (m.indices.empty()) formatError("STL has no triangles");
    return m;
  }
  if (bytes.size() < 84)
    formatError("binary STL is truncated: " + std::to_string(bytes.size()) + " bytes, under the 84-byte header");
  const std::uint64_t expected = 84 + 50 * std::uint64_t(get32(bytes.data() + 80));
  formatError("binary STL size " + std::to_string(bytes.size()) + " does not match its triangle count (" +
              std::to_string(expected) + " bytes expected)" + (bytes.size() < expected ? ": truncated" : ""));
}

}  // namespace marzipan
