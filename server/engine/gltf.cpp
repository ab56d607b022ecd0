// glTF 2.0 binary export (conventions in gltf.hpp). The JSON chunk is written by hand: the
// engine links no JSON library and the document has a fixed shape.
#include "gltf.hpp"

#include <bit>
#include <charconv>
#include <cmath>
#include <limits>
#include <string>

#include "color_space.hpp"
#include "errors.hpp"
#include "little_endian.hpp"
#include "mesh_io.hpp"

namespace marzipan {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr std::uint32_t kJsonChunk = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kBinChunk = 0x004E4942;   // "BIN\0"
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kFloat = 5126, kUnsignedInt = 5125;

// Nine significant digits: parsing gives back the same float, which the validator compares
// against the accessor's data.
std::string number(float f) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, f, std::chars_format::general, 9);
  return std::string(buf, r.ptr);
}

std::string vec3(const float v[3]) {
  std::string s = "[";
  for (int a = 0; a < 3; ++a) s.append(a ? "," : "").append(number(v[a]));
  return s.append("]");
}

// Unit normals per vertex: the mesh's own, normalized, or the area-weighted triangle normal.
std::vector<float> unitNormals(const Mesh& m) {
  std::vector<float> n(m.normals);
  std::vector<double> fallback;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    float* p = &n[3 * v];
    const double l = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
    if (l > 1e-12 && std::isfinite(l)) {
      for (int a = 0; a < 3; ++a) p[a] = float(p[a] / l);
      continue;
    }
    if (fallback.empty()) {
      fallback.assign(m.positions.size(), 0.0);
      for (std::size_t t = 0; t < m.triangleCount(); ++t) {
        const std::uint32_t* i = &m.indices[3 * t];
        const Vec3 f = cross(m.position(i[1]) - m.position(i[0]), m.position(i[2]) - m.position(i[0]));
        for (int k = 0; k < 3; ++k)
          for (int a = 0; a < 3; ++a) fallback[3 * std::size_t(i[k]) + std::size_t(a)] += f[a];
      }
    }
    const Vec3 f = normalized(Vec3{fallback[3 * v], fallback[3 * v + 1], fallback[3 * v + 2]});
    const bool ok = length(f) > 0.5;
    p[0] = ok ? float(f.x) : 0.0f, p[1] = ok ? float(f.y) : 0.0f, p[2] = ok ? float(f.z) : 1.0f;
  }
  return n;
}

}  // namespace

std::vector<std::uint8_t> exportGlb(const Mesh& m) {
  requireExportable(m);
  for (const float f : m.positions)
    if (!std::isfinite(f)) throw EngineError(ErrorKind::InvalidArgument, "mesh", "positions must be finite");
  const std::size_t vertices = m.vertexCount(), indexCount = m.indices.size();
  const bool hasNormals = !m.normals.empty(), hasColors = !m.colors.empty();
  const std::size_t positionBytes = 12 * vertices, normalBytes = hasNormals ? positionBytes : 0;
  const std::size_t colorBytes = hasColors ? positionBytes : 0;
  const std::size_t indexBytes = 4 * indexCount;
  const std::size_t binBytes = positionBytes + normalBytes + colorBytes + indexBytes;  // each a multiple of 4
  if (binBytes > std::numeric_limits<std::uint32_t>::max() / 2)
    throw EngineError(ErrorKind::TooLarge, "mesh", "the mesh needs more than 2 GiB of glTF buffer");

  std::string json = R"({"asset":{"version":"2.0","generator":"Marzipan"},"scene":0,)";
  if (vertices == 0 || indexCount == 0) {
    // glTF forbids empty accessors: an empty solid is a scene without nodes.
    json += R"("scenes":[{}]})";
  } else {
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = m.positions[std::size_t(a)];
    for (std::size_t v = 0; v < vertices; ++v)
      for (int a = 0; a < 3; ++a) {
        const float f = m.positions[3 * v + std::size_t(a)];
        lo[a] = std::min(lo[a], f), hi[a] = std::max(hi[a], f);
      }
    const std::string nv = std::to_string(vertices), ni = std::to_string(indexCount);
    // Accessor i reads buffer view i: positions, [normals], [colours], indices.
    const int colorView = hasNormals ? 2 : 1;
    const int indexView = colorView + (hasColors ? 1 : 0);
    json += R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"name":"solid"}],)";
    json += R"("meshes":[{"name":"solid","primitives":[{"attributes":{"POSITION":0)";
    if (hasNormals) json += R"(,"NORMAL":1)";
    if (hasColors) json += R"(,"COLOR_0":)" + std::to_string(colorView);
    json += R"(},"indices":)" + std::to_string(indexView) + R"(,"mode":4}]}],)";
    json += R"("accessors":[{"bufferView":0,"componentType":)" + std::to_string(kFloat) + R"(,"count":)" + nv +
            R"(,"type":"VEC3","min":)" + vec3(lo) + R"(,"max":)" + vec3(hi) + "}";
    if (hasNormals)
      json += R"(,{"bufferView":1,"componentType":)" + std::to_string(kFloat) +
              R"(,"count":)" + nv + R"(,"type":"VEC3"})";
    if (hasColors)
      json += R"(,{"bufferView":)" + std::to_string(colorView) + R"(,"componentType":)" + std::to_string(kFloat) +
              R"(,"count":)" + nv + R"(,"type":"VEC3"})";
    json += R"(,{"bufferView":)" + std::to_string(indexView) + R"(,"componentType":)" + std::to_string(kUnsignedInt) +
            R"(,"count":)" + ni + R"(,"type":"SCALAR"}],)";
    json += R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" + std::to_string(positionBytes) +
            R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    if (hasNormals)
      json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes) + R"(,"byteLength":)" +
              std::to_string(normalBytes) + R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    if (hasColors)
      json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes + normalBytes) + R"(,"byteLength":)" +
              std::to_string(colorBytes) + R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes + normalBytes + colorBytes) +
            R"(,"byteLength":)" +
            std::to_string(indexBytes) + R"(,"target":)" + std::to_string(kElementArrayBuffer) + "}],";
    json += R"("buffers":[{"byteLength":)" + std::to_string(binBytes) + "}]}";
  }
  while (json.size() % 4) json += ' ';

  const bool hasBin = binBytes > 0 && indexCount > 0;
  const std::size_t total = 12 + 8 + json.size() + (hasBin ? 8 + binBytes : 0);
  std::vector<std::uint8_t> out;
  out.reserve(total);
  le::append32(out, kGlbMagic);
  le::append32(out, 2);
  le::append32(out, std::uint32_t(total));
  le::append32(out, std::uint32_t(json.size()));
  le::append32(out, kJsonChunk);
  out.insert(out.end(), json.begin(), json.end());
  if (hasBin) {
    le::append32(out, std::uint32_t(binBytes));
    le::append32(out, kBinChunk);
    for (const float f : m.positions) le::appendF32(out, f);
    if (hasNormals)
      for (const float f : unitNormals(m)) le::appendF32(out, f);
    if (hasColors)
      for (const std::uint8_t c : m.colors) le::appendF32(out, srgbToLinear(c));
    for (const std::uint32_t i : m.indices) le::append32(out, i);
  }
  return out;
}

}  // namespace marzipan
