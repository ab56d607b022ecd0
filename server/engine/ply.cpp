#include "ply.hpp"

#include <bit>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>

#include "little_endian.hpp"
#include "mesh_reading.hpp"

namespace marzipan {

using namespace mesh_reading;
using le::append32;
using le::appendF32;

namespace {

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

std::vector<std::uint8_t> exportPly(const Mesh& m) {
  requireExportable(m);
  const bool normals = !m.normals.empty();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment Marzipan mesh\nelement vertex " +
                       std::to_string(m.vertexCount()) + "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  const bool colors = !m.colors.empty();
  if (colors) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header +=
      "element face " + std::to_string(m.triangleCount()) + "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::vector<std::uint8_t> out(header.begin(), header.end());
  out.reserve(out.size() + m.vertexCount() * ((normals ? 24 : 12) + (colors ? 3 : 0)) + m.triangleCount() * 13);
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    for (int a = 0; a < 3; ++a) appendF32(out, m.positions[3 * v + std::size_t(a)]);
    if (normals)
      for (int a = 0; a < 3; ++a) appendF32(out, m.normals[3 * v + std::size_t(a)]);
    if (colors) out.insert(out.end(), m.colors.begin() + std::ptrdiff_t(3 * v), m.colors.begin() + std::ptrdiff_t(3 * v + 3));
  }
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    out.push_back(3);
    for (int k = 0; k < 3; ++k) append32(out, m.indices[3 * t + std::size_t(k)]);
  }
  return out;
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
      if (binaryLE) lineError(lines.number, "the format line is repeated");
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
      // What is read of an element is appended to the mesh, so a second vertex (or face)
      // element would add positions that the first one's normals or indices do not cover.
      for (const PlyElement& seen : elements)
        if (seen.name == e.name) lineError(lines.number, "element \"" + e.name.substr(0, 40) + "\" is repeated");
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
      if (p.name.empty()) lineError(lines.number, "property has no name");
      for (const PlyProperty& seen : elements.back().props)
        if (seen.name == p.name) lineError(lines.number, "property \"" + p.name.substr(0, 40) + "\" is repeated");
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
      int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1, red = -1, green = -1, blue = -1;
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
                    : q.name == "red"   ? &red
                    : q.name == "green" ? &green
                    : q.name == "blue"  ? &blue
                                        : nullptr;
        if (slot) *slot = int(i);
      }
      if (x < 0 || y < 0 || z < 0) formatError("PLY vertices need x, y and z");
      if (stride == 0 || e.count > left / stride)
        formatError("PLY is truncated: " + std::to_string(e.count) + " vertices do not fit");
      const bool withNormals = nx >= 0 && ny >= 0 && nz >= 0;
      const bool withColors = red >= 0 && green >= 0 && blue >= 0;
      m.positions.reserve(std::size_t(e.count) * 3);
      if (withNormals) m.normals.reserve(std::size_t(e.count) * 3);
      if (withColors) m.colors.reserve(std::size_t(e.count) * 3);
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
        if (withColors)
          for (const int k : {red, green, blue}) {
            const PlyScalar type = e.props[std::size_t(k)].type;
            const double c = readScalar(p + offset[std::size_t(k)], type) * (type.isFloat ? 255.0 : 1.0);
            if (!(c >= 0 && c <= 255))
              formatError("vertex " + std::to_string(v) + ": colour outside " + (type.isFloat ? "0..1" : "0..255"));
            m.colors.push_back(std::uint8_t(std::lround(c)));
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

}  // namespace marzipan
