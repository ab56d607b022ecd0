#include "obj.hpp"

#include <charconv>
#include <cmath>

#include "mesh_reading.hpp"

namespace marzipan {

using namespace mesh_reading;

namespace {

void appendFloat(std::string& s, float f) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, f, std::chars_format::general, 9);
  s.append(buf, r.ptr);
}

// A colour byte c as c / 255 with 4 significant digits (1 and 0 bare), within 0.0004 of it:
// reading it back times 255 rounds to c again.
void appendChannel(std::string& s, std::uint8_t c) {
  char buf[16];
  const auto r = std::to_chars(buf, buf + sizeof buf, double(c) / 255.0, std::chars_format::general, 4);
  s.append(buf, r.ptr);
}

void appendUint(std::string& s, std::uint64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

}  // namespace

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
  const bool colors = !m.colors.empty();
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    triple("v", m.positions, v);
    if (!colors) continue;
    s.pop_back();
    for (int a = 0; a < 3; ++a) {
      s += ' ';
      appendChannel(s, m.colors[3 * v + std::size_t(a)]);
    }
    s += '\n';
  }
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

Mesh parseObj(std::string_view text) {
  Lines lines{text};
  std::string_view line;
  Mesh m;
  std::vector<float> normals;
  std::vector<std::uint8_t> colors;
  bool allColored = true;
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
      if (kw == "vn") continue;
      std::string_view more[4];
      int extra = 0;
      while (extra < 4 && !(more[extra] = token(rest)).empty()) ++extra;
      if (extra != 3) {
        allColored = false;  // "v x y z" or "v x y z w"
        continue;
      }
      for (int a = 0; a < 3; ++a) {
        float c;
        if (!parseFloat(more[a], c) || !(c >= 0 && c <= 1))
          lineError(lines.number, "a vertex colour must be three numbers in 0..1");
        colors.push_back(std::uint8_t(std::lround(double(c) * 255.0)));
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
  if (allColored) m.colors = std::move(colors);
  return m;
}

}  // namespace marzipan
