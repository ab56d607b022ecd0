// Mesh export, parsing and mesh-to-volume import (conventions in mesh_io.hpp).
#include "mesh_io.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <numbers>
#include <unordered_map>

#include "errors.hpp"
#include "gltf.hpp"
#include "little_endian.hpp"

namespace marzipan {

namespace {

[[noreturn]] void formatError(const std::string& what) { throw EngineError(ErrorKind::Format, "mesh", what); }

[[noreturn]] void lineError(std::size_t line, const std::string& what) {
  formatError("line " + std::to_string(line) + ": " + what);
}

using le::append32;
using le::appendF32;
using le::get32;
using le::getF32;


void appendFloat(std::string& s, float f) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, f, std::chars_format::general, 9);
  s.append(buf, r.ptr);
}

void appendUint(std::string& s, std::uint64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

// Merges vertices at bit-identical positions (0 and -0 alike), in order of first use.
struct PositionKey {
  std::uint32_t x, y, z;
  friend bool operator==(const PositionKey&, const PositionKey&) = default;
};
struct PositionHash {
  std::size_t operator()(const PositionKey& k) const {
    std::uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
    h = (h ^ k.y) * 0xC2B2AE3D27D4EB4Full;
    h = (h ^ k.z) * 0x165667B19E3779F9ull;
    return std::size_t(h ^ (h >> 32));
  }
};

class Welder {
 public:
  std::uint32_t add(float x, float y, float z) {
    const PositionKey k{bits(x), bits(y), bits(z)};
    const auto [it, fresh] = index_.try_emplace(k, std::uint32_t(positions.size() / 3));
    if (fresh) positions.insert(positions.end(), {x, y, z});
    return it->second;
  }
  std::vector<float> positions;

 private:
  static std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f == 0 ? 0.0f : f); }
  std::unordered_map<PositionKey, std::uint32_t, PositionHash> index_;
};

// --- text scanning -------------------------------------------------------------------------

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

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// Splits off the next whitespace-separated token; empty at the end of the line.
std::string_view token(std::string_view& s) {
  std::size_t i = 0;
  while (i < s.size() && isSpace(s[i])) ++i;
  std::size_t j = i;
  while (j < s.size() && !isSpace(s[j])) ++j;
  const std::string_view t = s.substr(i, j - i);
  s.remove_prefix(j);
  return t;
}

bool parseFloat(std::string_view t, float& out) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  const auto r = std::from_chars(t.data(), t.data() + t.size(), out);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

float coordinate(std::string_view t, std::size_t line) {
  float f;
  if (!parseFloat(t, f)) lineError(line, "expected a number, got \"" + std::string(t.substr(0, 40)) + "\"");
  if (!std::isfinite(f)) lineError(line, "coordinate is not finite");
  return f;
}

void checkTriangleCount(std::size_t n) {
  if (n > kMaxMeshTriangles) formatError("more than " + std::to_string(kMaxMeshTriangles) + " triangles");
}

// --- STL -----------------------------------------------------------------------------------

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

// --- PLY -----------------------------------------------------------------------------------

struct PlyScalar {
  int size = 0;
  bool isFloat = false, isSigned = false;
};

std::optional<PlyScalar> plyScalar(std::string_view t) {
  if (t == "char" || t == "int8") return PlyScalar{1, false, true};
  if (t == "uchar" || t == "uint8") return PlyScalar{1, false, false};
  if (t == "short" || t == "int16") return PlyScalar{2, false, true};
  if (t == "ushort" || t == "uint16") return PlyScalar{2, false, false};
  if (t == "int" || t == "int32") return PlyScalar{4, false, true};
  if (t == "uint" || t == "uint32") return PlyScalar{4, false, false};
  if (t == "float" || t == "float32") return PlyScalar{4, true, true};
  if (t == "double" || t == "float64") return PlyScalar{8, true, true};
  return std::nullopt;
}

double readScalar(const std::uint8_t* p, PlyScalar s) {
  std::uint64_t u = 0;
  for (int i = 0; i < s.size; ++i) u |= std::uint64_t(p[i]) << (8 * i);
  if (s.isFloat) return s.size == 4 ? double(std::bit_cast<float>(std::uint32_t(u))) : std::bit_cast<double>(u);
  if (s.isSigned && s.size < 8 && (u >> (8 * s.size - 1) & 1))
    return double(std::int64_t(u) - (std::int64_t(1) << (8 * s.size)));
  return double(u);
}

struct PlyProperty {
  std::string name;
  PlyScalar type;
  bool list = false;
  PlyScalar countType;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

}  // namespace

void requireExportable(const Mesh& m) {
  if (m.positions.size() % 3 != 0 || m.indices.size() % 3 != 0)
    throw EngineError(ErrorKind::InvalidArgument, "mesh", "positions and indices must come in threes");
  if (!m.normals.empty() && m.normals.size() != m.positions.size())
    throw EngineError(ErrorKind::InvalidArgument, "mesh", "normals must be empty or one per vertex");
  for (const std::uint32_t i : m.indices)
    if (i >= m.vertexCount()) throw EngineError(ErrorKind::InvalidArgument, "mesh", "vertex index out of range");
  if (m.triangleCount() > std::numeric_limits<std::uint32_t>::max())
    throw EngineError(ErrorKind::TooLarge, "mesh", "more than 2^32 - 1 triangles");
}

std::optional<MeshFormat> meshFormatFromName(std::string_view name) {
  if (name == "stl") return MeshFormat::Stl;
  if (name == "obj") return MeshFormat::Obj;
  if (name == "ply") return MeshFormat::Ply;
  if (name == "glb") return MeshFormat::Glb;
  return std::nullopt;
}

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

std::string exportObj(const Mesh& m) {
  requireExportable(m);
  std::string s = "# Marzipan mesh: " + std::to_string(m.vertexCount()) + " vertices, " +
                  std::to_string(m.triangleCount()) + " triangles\n";
  s.reserve(s.size() + m.vertexCount() * 80 + m.triangleCount() * 40);
  auto triple = [&](const char* tag, const std::vector<float>& v, std::size_t i) {
    s += tag;
    for (int a = 0; a < 3; ++a) {
      s += ' ';
      appendFloat(s, v[3 * i + std::size_t(a)]);
    }
    s += '\n';
  };
  for (std::size_t v = 0; v < m.vertexCount(); ++v) triple("v", m.positions, v);
  const bool normals = !m.normals.empty();
  if (normals)
    for (std::size_t v = 0; v < m.vertexCount(); ++v) triple("vn", m.normals, v);
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    s += 'f';
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t i = std::uint64_t(m.indices[3 * t + std::size_t(k)]) + 1;
      s += ' ';
      appendUint(s, i);
      if (normals) {
        s += "//";
        appendUint(s, i);
      }
    }
    s += '\n';
  }
  return s;
}

std::vector<std::uint8_t> exportPly(const Mesh& m) {
  requireExportable(m);
  const bool normals = !m.normals.empty();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment Marzipan mesh\nelement vertex " +
                       std::to_string(m.vertexCount()) + "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  header +=
      "element face " + std::to_string(m.triangleCount()) + "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::vector<std::uint8_t> out(header.begin(), header.end());
  out.reserve(out.size() + m.vertexCount() * (normals ? 24 : 12) + m.triangleCount() * 13);
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    for (int a = 0; a < 3; ++a) appendF32(out, m.positions[3 * v + std::size_t(a)]);
    if (normals)
      for (int a = 0; a < 3; ++a) appendF32(out, m.normals[3 * v + std::size_t(a)]);
  }
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    out.push_back(3);
    for (int k = 0; k < 3; ++k) append32(out, m.indices[3 * t + std::size_t(k)]);
  }
  return out;
}

std::vector<std::uint8_t> exportMesh(const Mesh& m, MeshFormat format) {
  switch (format) {
    case MeshFormat::Stl:
      return exportStl(m);
    case MeshFormat::Obj: {
      const std::string s = exportObj(m);
      return {s.begin(), s.end()};
    }
    case MeshFormat::Ply:
      return exportPly(m);
    case MeshFormat::Glb:
      return exportGlb(m);
  }
  throw EngineError(ErrorKind::InvalidArgument, "format", "unknown mesh format");
}

void writeFile(const std::string& path, std::span<const std::uint8_t> bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (f) f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!f) throw EngineError(ErrorKind::InvalidArgument, "path", "cannot write " + path);
}

void writeFile(const std::string& path, std::string_view text) {
  writeFile(path, std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

Mesh parseObj(std::string_view text) {
  Lines lines{text};
  std::string_view line;
  Mesh m;
  std::vector<float> normals;
  // Raw (vertex, normal) references per face corner, resolved once all vertices are known.
  struct Corner {
    std::int64_t v, n;
    std::size_t line;
  };
  std::vector<Corner> corners;
  std::vector<std::uint32_t> faceSizes;
  auto index = [&](std::string_view t, std::size_t count, std::size_t lineNo) -> std::int64_t {
    std::int64_t i = 0;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), i);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || i == 0)
      lineError(lineNo, "bad index \"" + std::string(t.substr(0, 40)) + "\"");
    if (i < 0) {
      i += std::int64_t(count);
      if (i < 0) lineError(lineNo, "relative index before the first vertex");
      return i;
    }
    return i - 1;
  };
  while (lines.next(line)) {
    std::string_view rest = line.substr(0, line.find('#'));
    const std::string_view kw = token(rest);
    if (kw == "v" || kw == "vn") {
      std::vector<float>& dst = kw == "v" ? m.positions : normals;
      for (int a = 0; a < 3; ++a) {
        const std::string_view t = token(rest);
        if (t.empty()) lineError(lines.number, "expected three coordinates");
        dst.push_back(coordinate(t, lines.number));
      }
    } else if (kw == "f") {
      std::uint32_t n = 0;
      for (std::string_view t = token(rest); !t.empty(); t = token(rest), ++n) {
        const std::size_t s1 = t.find('/');
        Corner c{index(t.substr(0, s1), m.positions.size() / 3, lines.number), -1, lines.number};
        if (s1 != std::string_view::npos) {
          const std::size_t s2 = t.find('/', s1 + 1);
          if (s2 != std::string_view::npos && s2 + 1 < t.size())
            c.n = index(t.substr(s2 + 1), normals.size() / 3, lines.number);
        }
        corners.push_back(c);
      }
      if (n < 3) lineError(lines.number, "a face needs at least 3 vertices");
      faceSizes.push_back(n);
      checkTriangleCount(corners.size());
    }
  }
  const std::size_t nv = m.positions.size() / 3;
  bool keepNormals = normals.size() == m.positions.size();
  for (const Corner& c : corners) {
    if (std::uint64_t(c.v) >= nv) lineError(c.line, "vertex index " + std::to_string(c.v + 1) + " out of range");
    keepNormals = keepNormals && c.n == c.v;
  }
  std::size_t at = 0;
  for (const std::uint32_t n : faceSizes) {
    for (std::uint32_t k = 1; k + 1 < n; ++k)
      m.indices.insert(m.indices.end(), {std::uint32_t(corners[at].v), std::uint32_t(corners[at + k].v),
                                         std::uint32_t(corners[at + k + 1].v)});
    at += n;
  }
  if (m.indices.empty()) formatError("OBJ has no faces");
  if (keepNormals) m.normals = std::move(normals);
  return m;
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

Mesh parsePly(std::span<const std::uint8_t> bytes) {
  const std::string_view all(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  const std::size_t end = all.find("end_header\n");
  if (all.substr(0, 4) != "ply\n" && all.substr(0, 5) != "ply\r\n") formatError("PLY does not start with \"ply\"");
  if (end == std::string_view::npos) formatError("PLY header has no end_header line");
  Lines lines{all.substr(0, end)};
  std::string_view line;
  std::vector<PlyElement> elements;
  bool binaryLE = false;
  lines.next(line);
  while (lines.next(line)) {
    std::string_view rest = line;
    const std::string_view kw = token(rest);
    if (kw == "format") {
      const std::string_view f = token(rest);
      if (f != "binary_little_endian") lineError(lines.number, "only binary_little_endian PLY is supported");
      binaryLE = true;
    } else if (kw == "element") {
      PlyElement e;
      e.name = std::string(token(rest));
      const std::string_view c = token(rest);
      const auto r = std::from_chars(c.data(), c.data() + c.size(), e.count);
      if (e.name.empty() || r.ec != std::errc() || r.ptr != c.data() + c.size())
        lineError(lines.number, "bad element line");
      elements.push_back(std::move(e));
    } else if (kw == "property") {
      if (elements.empty()) lineError(lines.number, "property before any element");
      PlyProperty p;
      std::string_view t = token(rest);
      if (t == "list") {
        p.list = true;
        const auto ct = plyScalar(token(rest));
        if (!ct || ct->isFloat) lineError(lines.number, "bad list count type");
        p.countType = *ct;
        t = token(rest);
      }
      const auto type = plyScalar(t);
      if (!type) lineError(lines.number, "unknown property type \"" + std::string(t.substr(0, 40)) + "\"");
      p.type = *type;
      p.name = std::string(token(rest));
      elements.back().props.push_back(p);
    } else if (!kw.empty() && kw != "comment" && kw != "obj_info") {
      lineError(lines.number, "unknown header line");
    }
  }
  if (!binaryLE) formatError("PLY header has no format line");

  Mesh m;
  const std::uint8_t* p = bytes.data() + end + 11;
  const std::uint8_t* const stop = bytes.data() + bytes.size();
  bool sawVertices = false, sawFaces = false;
  for (const PlyElement& e : elements) {
    const std::size_t left = std::size_t(stop - p);
    if (e.name == "vertex") {
      int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1;
      std::size_t stride = 0;
      std::vector<std::size_t> offset;
      for (std::size_t i = 0; i < e.props.size(); ++i) {
        const PlyProperty& q = e.props[i];
        if (q.list) formatError("PLY vertex lists are not supported");
        offset.push_back(stride);
        stride += std::size_t(q.type.size);
        int* slot = q.name == "x"    ? &x
                    : q.name == "y"  ? &y
                    : q.name == "z"  ? &z
                    : q.name == "nx" ? &nx
                    : q.name == "ny" ? &ny
                    : q.name == "nz" ? &nz
                                     : nullptr;
        if (slot) *slot = int(i);
      }
      if (x < 0 || y < 0 || z < 0) formatError("PLY vertices need x, y and z");
      if (stride == 0 || e.count > left / stride)
        formatError("PLY is truncated: " + std::to_string(e.count) + " vertices do not fit");
      const bool withNormals = nx >= 0 && ny >= 0 && nz >= 0;
      m.positions.reserve(std::size_t(e.count) * 3);
      if (withNormals) m.normals.reserve(std::size_t(e.count) * 3);
      for (std::uint64_t v = 0; v < e.count; ++v, p += stride) {
        for (const int k : {x, y, z}) {
          const double c = readScalar(p + offset[std::size_t(k)], e.props[std::size_t(k)].type);
          if (!std::isfinite(c) || std::fabs(c) > std::numeric_limits<float>::max())
            formatError("vertex " + std::to_string(v) + ": coordinate is not finite");
          m.positions.push_back(float(c));
        }
        if (withNormals)
          for (const int k : {nx, ny, nz}) {
            const double c = readScalar(p + offset[std::size_t(k)], e.props[std::size_t(k)].type);
            if (!std::isfinite(c) || std::fabs(c) > std::numeric_limits<float>::max())
              formatError("vertex " + std::to_string(v) + ": normal is not finite");
            m.normals.push_back(float(c));
          }
      }
      sawVertices = true;
    } else if (e.name == "face") {
      if (e.props.size() != 1 || !e.props[0].list || e.props[0].type.isFloat)
        formatError("PLY faces need exactly one integer list property");
      const PlyProperty& q = e.props[0];
      const std::size_t cs = std::size_t(q.countType.size), is = std::size_t(q.type.size);
      if (e.count > left / (cs + 3 * is))
        formatError("PLY is truncated: " + std::to_string(e.count) + " faces do not fit");
      checkTriangleCount(e.count);
      m.indices.reserve(std::size_t(e.count) * 3);
      for (std::uint64_t f = 0; f < e.count; ++f) {
        if (std::size_t(stop - p) < cs) formatError("PLY is truncated in face " + std::to_string(f));
        const double n = readScalar(p, q.countType);
        p += cs;
        if (n < 3) formatError("PLY face " + std::to_string(f) + " has fewer than 3 vertices");
        if (double(std::size_t(stop - p) / is) < n) formatError("PLY is truncated in face " + std::to_string(f));
        std::vector<std::uint32_t> poly;
        for (std::size_t k = 0; k < std::size_t(n); ++k, p += is) {
          const double i = readScalar(p, q.type);
          if (i < 0 || i >= double(m.vertexCount()))
            formatError("PLY face " + std::to_string(f) + ": vertex index out of range");
          poly.push_back(std::uint32_t(i));
        }
        for (std::size_t k = 1; k + 1 < poly.size(); ++k)
          m.indices.insert(m.indices.end(), {poly[0], poly[k], poly[k + 1]});
        checkTriangleCount(m.indices.size() / 3);
      }
      sawFaces = true;
    } else {
      std::size_t stride = 0;
      for (const PlyProperty& q : e.props) {
        if (q.list) formatError("PLY element \"" + e.name + "\" has a list property and cannot be skipped");
        stride += std::size_t(q.type.size);
      }
      if (stride != 0 && e.count > left / stride) formatError("PLY is truncated in element \"" + e.name + "\"");
      p += std::size_t(e.count) * stride;
    }
    if (sawFaces && !sawVertices) formatError("PLY faces come before the vertices");
  }
  if (m.indices.empty()) formatError("PLY has no faces");
  return m;
}

Mesh parseMesh(std::span<const std::uint8_t> bytes, MeshFormat format) {
  switch (format) {
    case MeshFormat::Stl:
      return parseStl(bytes);
    case MeshFormat::Obj:
      return parseObj(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
    case MeshFormat::Ply:
      return parsePly(bytes);
    case MeshFormat::Glb:
      throw EngineError(ErrorKind::Format, "format", "glTF files are written, not read");
  }
  throw EngineError(ErrorKind::InvalidArgument, "format", "unknown mesh format");
}

Mesh fitMeshToDomain(const Mesh& m, Int3 dims, double margin) {
  requireFinite(margin, "margin");
  if (m.vertexCount() == 0) formatError("mesh has no vertices");
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const Vec3 p = m.position(v);
    if (!isFinite(p)) formatError("coordinate is not finite");
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
  }
  double scale = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double room = dims[a] - 1 - 2 * margin;
    if (!(room > 0)) throw EngineError(ErrorKind::InvalidArgument, "margin", "leaves no room in the domain");
    if (hi[a] > lo[a]) scale = std::min(scale, room / (hi[a] - lo[a]));
  }
  if (!std::isfinite(scale)) formatError("mesh has no extent");
  Mesh out = m;
  for (std::size_t v = 0; v < m.vertexCount(); ++v)
    for (int a = 0; a < 3; ++a) {
      const double c = (m.positions[3 * v + std::size_t(a)] - 0.5 * (lo[a] + hi[a])) * scale + 0.5 * (dims[a] - 1);
      out.positions[3 * v + std::size_t(a)] = float(c);
    }
  return out;
}

// --- mesh to volume ------------------------------------------------------------------------

namespace {

enum Feature : std::uint8_t { kFace, kVertex0, kVertex1, kVertex2, kEdge01, kEdge12, kEdge20 };

struct Triangle {
  Vec3 a, b, c;
  Vec3 centre;
  double radius;
  std::uint32_t v[3];
  Vec3 normal;    // unit face normal
  Vec3 edgeN[3];  // pseudonormals of edges 01, 12, 20
};

// Closest point of t to p (Ericson, Real-Time Collision Detection 5.1.5) and the feature it
// lies on; the feature picks the pseudonormal that decides the sign.
Vec3 closestPoint(const Triangle& t, Vec3 p, Feature& f) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return f = kVertex0, t.a;
  const Vec3 bp = p - t.b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return f = kVertex1, t.b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return f = kEdge01, t.a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - t.c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return f = kVertex2, t.c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return f = kEdge20, t.a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return f = kEdge12, t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  f = kFace;
  return t.a + ab * (vb * denom) + ac * (vc * denom);
}

double distanceSquared(const Triangle& t, Vec3 p) {
  Feature f;
  const Vec3 d = p - closestPoint(t, p, f);
  return dot(d, d);
}

// Solid angle of the triangle seen from p (Van Oosterom and Strackee), positive when p sees
// its back (inside for an outward triangle).
double solidAngle(const Triangle& t, Vec3 p) {
  const Vec3 a = t.a - p, b = t.b - p, c = t.c - p;
  const double la = length(a), lb = length(b), lc = length(c);
  const double num = dot(a, cross(b, c));
  const double den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
  return 2 * std::atan2(num, den);
}

double angleAt(Vec3 p, Vec3 q, Vec3 r) {
  const Vec3 u = normalized(q - p), w = normalized(r - p);
  return std::acos(std::clamp(dot(u, w), -1.0, 1.0));
}

std::uint64_t edgeKey(std::uint32_t a, std::uint32_t b) { return std::uint64_t(std::min(a, b)) << 32 | std::max(a, b); }

}  // namespace

Volume importMesh(const Mesh& m, Int3 dims, float band, ThreadPool& pool) {
  Volume vol(dims, band);  // validates dims and band first
  if (m.positions.size() % 3 != 0 || m.indices.size() % 3 != 0)
    formatError("positions and indices must come in threes");
  if (m.indices.empty()) formatError("mesh has no triangles");
  checkTriangleCount(m.triangleCount());
  for (const float c : m.positions)
    if (!std::isfinite(c)) formatError("coordinate is not finite");
  for (const std::uint32_t i : m.indices)
    if (i >= m.vertexCount()) formatError("vertex index " + std::to_string(i) + " out of range");

  // Merge vertices at identical positions, drop triangles that collapse.
  Welder w;
  std::vector<std::uint32_t> remap(m.vertexCount());
  for (std::size_t v = 0; v < m.vertexCount(); ++v)
    remap[v] = w.add(m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]);
  Mesh mesh;
  mesh.positions = std::move(w.positions);
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const std::uint32_t a = remap[m.indices[3 * t]], b = remap[m.indices[3 * t + 1]], c = remap[m.indices[3 * t + 2]];
    if (a != b && b != c && c != a) mesh.indices.insert(mesh.indices.end(), {a, b, c});
  }
  if (mesh.indices.empty()) formatError("mesh has only degenerate triangles");
  const EdgeCheck check = checkEdges(mesh);
  if (check.boundary)
    formatError("mesh is not closed: " + std::to_string(check.boundary) + " edges belong to a single triangle");
  if (check.nonManifold)
    formatError("mesh is not manifold: " + std::to_string(check.nonManifold) +
                " edges belong to more than two triangles");
  if (check.misoriented)
    formatError("mesh is not consistently oriented: " + std::to_string(check.misoriented) +
                " edges run the same way in both their triangles");
  if (meshVolume(mesh) < 0)
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) std::swap(mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]);

  // Triangles with unit normals; angle-weighted vertex pseudonormals; edge pseudonormals as the
  // sum of the two faces' normals (the mesh is closed, so every edge has exactly two).
  const std::size_t nt = mesh.triangleCount();
  std::vector<Triangle> tris(nt);
  std::vector<Vec3> vertexN(mesh.vertexCount());
  std::unordered_map<std::uint64_t, Vec3> edgeSum;
  edgeSum.reserve(nt * 3 / 2);
  for (std::size_t t = 0; t < nt; ++t) {
    Triangle& tr = tris[t];
    for (int k = 0; k < 3; ++k) tr.v[k] = mesh.indices[3 * t + std::size_t(k)];
    tr.a = mesh.position(tr.v[0]), tr.b = mesh.position(tr.v[1]), tr.c = mesh.position(tr.v[2]);
    tr.normal = normalized(cross(tr.b - tr.a, tr.c - tr.a));
    tr.centre = (tr.a + tr.b + tr.c) / 3.0;
    tr.radius = std::max({length(tr.a - tr.centre), length(tr.b - tr.centre), length(tr.c - tr.centre)});
    const Vec3 p[3] = {tr.a, tr.b, tr.c};
    for (int k = 0; k < 3; ++k) {
      if (tr.normal == Vec3{}) break;
      vertexN[tr.v[k]] = vertexN[tr.v[k]] + tr.normal * angleAt(p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
      Vec3& e = edgeSum[edgeKey(tr.v[k], tr.v[(k + 1) % 3])];
      e = e + tr.normal;
    }
  }
  for (Triangle& tr : tris)
    for (int k = 0; k < 3; ++k) tr.edgeN[k] = edgeSum[edgeKey(tr.v[k], tr.v[(k + 1) % 3])];

  // Bin triangles into the bricks they can reach within the band: every voxel of a brick lies
  // within half a diagonal of its centre. Zero-area triangles are left out (their points lie on
  // neighbouring triangles' edges, and they have no normal).
  const Int3 bd = vol.brickDims();
  const double halfDiagonal = 0.5 * (kBrickSide - 1) * std::sqrt(3.0);
  const double reach = band + halfDiagonal + 1e-6;
  auto brickIndex = [&](Int3 b) {
    return std::size_t(b.x) + std::size_t(bd.x) * (std::size_t(b.y) + std::size_t(bd.y) * std::size_t(b.z));
  };
  const std::size_t nb = std::size_t(bd.x) * bd.y * bd.z;
  std::vector<std::uint32_t> start(nb + 1, 0);
  std::vector<std::uint32_t> binned;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint32_t> fill;
    if (pass == 1) {
      std::uint64_t total = 0;
      for (std::size_t i = 0; i < nb; ++i) {
        total += start[i + 1];
        if (total > std::numeric_limits<std::uint32_t>::max())
          throw EngineError(ErrorKind::TooLarge, "mesh", "too many triangle and brick pairs within the band");
        start[i + 1] = std::uint32_t(total);
      }
      binned.resize(start[nb]);
      fill.assign(start.begin(), start.end() - 1);
    }
    for (std::size_t t = 0; t < nt; ++t) {
      const Triangle& tr = tris[t];
      if (tr.normal == Vec3{}) continue;
      Int3 lo, hi;
      for (int a = 0; a < 3; ++a) {
        const double mn = std::min({tr.a[a], tr.b[a], tr.c[a]}) - band,
                     mx = std::max({tr.a[a], tr.b[a], tr.c[a]}) + band;
        lo[a] = int(std::clamp(std::floor(mn / kBrickSide), 0.0, double(bd[a])));
        hi[a] = int(std::clamp(std::floor(mx / kBrickSide), -1.0, double(bd[a] - 1)));
      }
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y)
          for (int x = lo.x; x <= hi.x; ++x) {
            const Vec3 centre{x * kBrickSide + 3.5, y * kBrickSide + 3.5, z * kBrickSide + 3.5};
            if (distanceSquared(tr, centre) > reach * reach) continue;
            const std::size_t b = brickIndex({x, y, z});
            if (pass == 0) {
              if (start[b + 1] == std::numeric_limits<std::uint32_t>::max())
                throw EngineError(ErrorKind::TooLarge, "mesh", "too many triangle and brick pairs within the band");
              ++start[b + 1];
            } else {
              binned[fill[b]++] = std::uint32_t(t);
            }
          }
    }
  }

  // Exact distances in the bricks that have candidates; NaN marks a voxel beyond the band.
  std::vector<Int3> near;
  std::vector<std::int32_t> nearIndex(nb, -1);
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x)
        if (start[brickIndex({x, y, z}) + 1] > start[brickIndex({x, y, z})]) {
          nearIndex[brickIndex({x, y, z})] = std::int32_t(near.size());
          near.push_back({x, y, z});
        }
  const float unknown = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::shared_ptr<Brick>> bricks(near.size());
  pool.parallelFor(near.size(), [&](std::size_t i) {
    auto br = std::make_shared<Brick>();
    const Int3 o{near[i].x * kBrickSide, near[i].y * kBrickSide, near[i].z * kBrickSide};
    const std::size_t b = brickIndex(near[i]);
    for (int z = 0; z < kBrickSide; ++z)
      for (int y = 0; y < kBrickSide; ++y)
        for (int x = 0; x < kBrickSide; ++x) {
          const Int3 g = o + Int3{x, y, z};
          float& out = br->v[x + kBrickSide * (y + kBrickSide * z)];
          if (g.x >= dims.x || g.y >= dims.y || g.z >= dims.z) {
            out = band;
            continue;
          }
          const Vec3 p{double(g.x), double(g.y), double(g.z)};
          double best = double(band) * band;
          const Triangle* bestTri = nullptr;
          Feature bestFeature = kFace;
          Vec3 bestPoint;
          for (std::uint32_t k = start[b]; k < start[b + 1]; ++k) {
            const Triangle& tr = tris[binned[k]];
            const Vec3 dc = p - tr.centre;
            const double cull = std::sqrt(best) + tr.radius;
            if (dot(dc, dc) > cull * cull) continue;
            Feature f;
            const Vec3 q = closestPoint(tr, p, f);
            const double d2 = dot(p - q, p - q);
            if (d2 < best) best = d2, bestTri = &tr, bestFeature = f, bestPoint = q;
          }
          if (!bestTri) {
            out = unknown;
            continue;
          }
          Vec3 n;
          switch (bestFeature) {
            case kFace:
              n = bestTri->normal;
              break;
            case kVertex0:
              n = vertexN[bestTri->v[0]];
              break;
            case kVertex1:
              n = vertexN[bestTri->v[1]];
              break;
            case kVertex2:
              n = vertexN[bestTri->v[2]];
              break;
            case kEdge01:
              n = bestTri->edgeN[0];
              break;
            case kEdge12:
              n = bestTri->edgeN[1];
              break;
            case kEdge20:
              n = bestTri->edgeN[2];
              break;
          }
          const float d = float(std::sqrt(best));
          out = dot(p - bestPoint, n) < 0 ? -d : d;
        }
    bricks[i] = std::move(br);
  });

  // Signs beyond the band, in z, y, x order: a voxel further than band (>= 2 vu) from the
  // surface has the sign of any neighbour, and its x-, y- or z-neighbour before it is settled.
  std::vector<std::uint8_t> farInside(nb, 0);
  std::optional<bool> seed;
  auto windingInside = [&](Vec3 p) {
    double sum = 0;
    for (const Triangle& tr : tris) sum += solidAngle(tr, p);
    return sum > 2 * std::numbers::pi;
  };
  auto insideAt = [&](Int3 g) {
    const std::size_t b = brickIndex({g.x >> 3, g.y >> 3, g.z >> 3});
    const std::int32_t ni = nearIndex[b];
    if (ni < 0) return farInside[b] != 0;
    return bricks[std::size_t(ni)]->v[(g.x & 7) + kBrickSide * ((g.y & 7) + kBrickSide * (g.z & 7))] < 0;
  };
  auto settle = [&](Int3 g) {
    if (g.x > 0) return insideAt(g - Int3{1, 0, 0});
    if (g.y > 0) return insideAt(g - Int3{0, 1, 0});
    if (g.z > 0) return insideAt(g - Int3{0, 0, 1});
    if (!seed) seed = windingInside({double(g.x), double(g.y), double(g.z)});
    return *seed;
  };
  std::vector<BrickChange> changes;
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) {
        const Int3 b{x, y, z};
        const std::int32_t ni = nearIndex[brickIndex(b)];
        const Int3 o{x * kBrickSide, y * kBrickSide, z * kBrickSide};
        if (ni < 0) {
          const bool in = settle(o);
          farInside[brickIndex(b)] = in;
          if (in) changes.push_back({b, {}, {nullptr, true}});
          continue;
        }
        Brick& br = *bricks[std::size_t(ni)];
        for (int k = 0; k < kBrickVoxels; ++k) {
          float& v = br.v[k];
          if (std::isnan(v)) v = settle(o + Int3{k & 7, k >> 3 & 7, k >> 6}) ? -band : band;
        }
        const BrickRef ref = vol.canonicalBrick(b, bricks[std::size_t(ni)]);
        if (ref.data || ref.inside) changes.push_back({b, {}, ref});
      }
  vol.publish(changes, true);
  return vol;
}

}  // namespace marzipan
