// glTF binary export: the container's bytes, and the buffer holding exactly the mesh. The
// document itself is checked by the Khronos validator in tests/gltf.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <string>

#include "engine/color_space.hpp"
#include "engine/errors.hpp"
#include "engine/gltf.hpp"
#include "engine/little_endian.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/mesh_io.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

TEST_CASE("a .glb holds the header, a JSON chunk and the mesh's buffer", "[gltf]") {
  const Mesh m = extractMesh(makeSolid(SolidKind::Torus, {40, 40, 40}));
  REQUIRE(m.triangleCount() > 1000);
  const auto glb = exportGlb(m);
  REQUIRE(exportMesh(m, MeshFormat::Glb) == glb);
  REQUIRE(glb.size() > 28);
  CHECK(std::string(glb.begin(), glb.begin() + 4) == "glTF");
  CHECK(le::get32(&glb[4]) == 2);
  CHECK(le::get32(&glb[8]) == glb.size());
  const std::uint32_t jsonLength = le::get32(&glb[12]);
  CHECK(jsonLength % 4 == 0);
  CHECK(std::string(glb.begin() + 16, glb.begin() + 20) == "JSON");
  const std::string json(glb.begin() + 20, glb.begin() + 20 + jsonLength);
  CHECK(json.find("\"count\":" + std::to_string(m.indices.size())) != std::string::npos);
  CHECK(json.find("\"count\":" + std::to_string(m.vertexCount())) != std::string::npos);
  CHECK(json.find("\"NORMAL\":1") != std::string::npos);

  const std::size_t bin = 20 + jsonLength;
  const std::uint32_t binLength = le::get32(&glb[bin]);
  CHECK(std::memcmp(&glb[bin + 4], "BIN\0", 4) == 0);
  REQUIRE(binLength == 24 * m.vertexCount() + 4 * m.indices.size());
  REQUIRE(bin + 8 + binLength == glb.size());
  const std::uint8_t* p = &glb[bin + 8];
  for (std::size_t i = 0; i < m.positions.size(); ++i) REQUIRE(le::getF32(p + 4 * i) == m.positions[i]);
  p += 12 * m.vertexCount();
  double worst = 0;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const Vec3 n{le::getF32(p + 12 * v), le::getF32(p + 12 * v + 4), le::getF32(p + 12 * v + 8)};
    worst = std::max(worst, std::fabs(length(n) - 1));
    REQUIRE(dot(n, m.normal(v)) > 0.999 * length(m.normal(v)));
  }
  CHECK(worst < 1e-6);
  p += 12 * m.vertexCount();
  for (std::size_t i = 0; i < m.indices.size(); ++i) REQUIRE(le::get32(p + 4 * i) == m.indices[i]);
}

TEST_CASE("a .glb without normals or triangles, and bad meshes", "[gltf][errors]") {
  Mesh tri;
  tri.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  tri.indices = {0, 1, 2};
  const auto glb = exportGlb(tri);
  const std::string json(glb.begin() + 20, glb.begin() + 20 + le::get32(&glb[12]));
  CHECK(json.find("NORMAL") == std::string::npos);
  CHECK(json.find("\"indices\":1") != std::string::npos);
  CHECK(json.find("\"min\":[0,0,0],\"max\":[1,1,0]") != std::string::npos);

  const auto empty = exportGlb(Mesh{});
  CHECK(le::get32(&empty[8]) == empty.size());
  CHECK(empty.size() == 20 + le::get32(&empty[12]));  // no binary chunk

  Mesh bad = tri;
  bad.indices = {0, 1, 3};
  CHECK_THROWS_AS(exportGlb(bad), EngineError);
  bad = tri;
  bad.positions[4] = std::nanf("");
  CHECK_THROWS_AS(exportGlb(bad), EngineError);
  bad = tri;
  bad.normals = {0, 0, 1};
  CHECK_THROWS_AS(exportGlb(bad), EngineError);
  // The triangle without normals reads back (a .glb was written only, before colour came).
  CHECK(parseMesh(glb, MeshFormat::Glb).positions == tri.positions);
}

namespace {

// The sRGB encoding of a linear value (IEC 61966-2-1), as a byte: the inverse of what COLOR_0
// holds, written out here apart from the exporter.
int srgbByte(double linear) {
  const double s = linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
  return int(std::lround(255 * s));
}

}  // namespace

TEST_CASE("a .glb's COLOR_0 holds the vertex colours in linear light, which encode back to the bytes", "[gltf][color]") {
  for (int c = 0; c < 256; ++c) {
    REQUIRE(srgbByte(srgbToLinear(std::uint8_t(c))) == c);
    REQUIRE(linearToSrgb(srgbToLinear(std::uint8_t(c))) == c);
  }
  CHECK(linearToSrgb(-0.5) == 0);
  CHECK(linearToSrgb(7) == 255);
  CHECK(srgbToLinear(0) == 0.0f);
  CHECK(srgbToLinear(255) == 1.0f);
  CHECK(srgbToLinear(10) == Approx(10 / 255.0 / 12.92).epsilon(1e-6));  // the linear toe
  CHECK(srgbToLinear(128) == Approx(0.2158605).epsilon(1e-6));          // the curve's middle

  Mesh m = extractMesh(makeSolid(SolidKind::Torus, {40, 40, 40}));
  m.colors.resize(m.positions.size());
  for (std::size_t i = 0; i < m.colors.size(); ++i) m.colors[i] = std::uint8_t(i * 37 % 256);
  const auto glb = exportGlb(m);
  const std::uint32_t jsonLength = le::get32(&glb[12]);
  const std::string json(glb.begin() + 20, glb.begin() + 20 + jsonLength);
  CHECK(json.find(R"("attributes":{"POSITION":0,"NORMAL":1,"COLOR_0":2},"indices":3)") != std::string::npos);
  CHECK(json.find(R"({"bufferView":2,"componentType":5126,"count":)" + std::to_string(m.vertexCount()) +
                  R"(,"type":"VEC3"})") != std::string::npos);
  const std::size_t bin = 20 + jsonLength;
  REQUIRE(le::get32(&glb[bin]) == 36 * m.vertexCount() + 4 * m.indices.size());
  const std::uint8_t* p = &glb[bin + 8 + 24 * m.vertexCount()];
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < m.colors.size(); ++i) wrong += srgbByte(le::getF32(p + 4 * i)) == m.colors[i] ? 0 : 1;
  CHECK(wrong == 0);
  p += 12 * m.vertexCount();
  for (std::size_t i = 0; i < m.indices.size(); ++i) REQUIRE(le::get32(p + 4 * i) == m.indices[i]);

  // Without normals the colours are accessor 1.
  m.normals.clear();
  const auto bare = exportGlb(m);
  const std::string bareJson(bare.begin() + 20, bare.begin() + 20 + le::get32(&bare[12]));
  CHECK(bareJson.find(R"("attributes":{"POSITION":0,"COLOR_0":1},"indices":2)") != std::string::npos);
}

TEST_CASE("a .glb reads back as the mesh it was written from, colours and all", "[gltf][color]") {
  Mesh m = extractMesh(makeSolid(SolidKind::Torus, {40, 40, 40}));
  m.colors.resize(m.positions.size());
  for (std::size_t i = 0; i < m.colors.size(); ++i) m.colors[i] = std::uint8_t(i * 37 % 256);
  const Mesh back = parseGlb(exportGlb(m));
  CHECK(back.positions == m.positions);
  CHECK(back.indices == m.indices);
  CHECK(back.colors == m.colors);
  CHECK(back.normals.empty());
  CHECK(parseMesh(exportMesh(m, MeshFormat::Glb), MeshFormat::Glb).colors == m.colors);
  m.colors.clear();
  CHECK(parseGlb(exportGlb(m)).colors.empty());
}

namespace {

// A .glb of the given JSON and binary chunk (padded as the format wants).
std::vector<std::uint8_t> glbOf(std::string json, std::vector<std::uint8_t> bin) {
  while (json.size() % 4) json += ' ';
  while (bin.size() % 4) bin.push_back(0);
  std::vector<std::uint8_t> out;
  le::append32(out, 0x46546C67);
  le::append32(out, 2);
  le::append32(out, std::uint32_t(12 + 8 + json.size() + (bin.empty() ? 0 : 8 + bin.size())));
  le::append32(out, std::uint32_t(json.size()));
  le::append32(out, 0x4E4F534A);
  out.insert(out.end(), json.begin(), json.end());
  if (!bin.empty()) {
    le::append32(out, std::uint32_t(bin.size()));
    le::append32(out, 0x004E4942);
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

std::string glbError(const std::vector<std::uint8_t>& b) {
  try {
    parseGlb(b);
  } catch (const EngineError& e) {
    return e.kind() == ErrorKind::Format ? std::string(e.what()) : std::string("not Format");
  }
  return "read";
}

// Two primitives sharing one interleaved vertex buffer (position, then an RGBA colour of
// normalized bytes, stride 16), the second without indices.
struct TwoPrimitives {
  std::vector<std::uint8_t> bin;
  std::string accessors = R"({"bufferView":0,"componentType":5126,"count":6,"type":"VEC3"},)"
                          R"({"bufferView":0,"byteOffset":12,"componentType":5121,"normalized":true,"count":6,"type":"VEC4"},)"
                          R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"})";
  TwoPrimitives() {
    for (int v = 0; v < 6; ++v) {
      for (float c : {float(v % 2), float(v / 2 % 2), float(v / 4)}) le::appendF32(bin, c);
      for (std::uint8_t c : {std::uint8_t(255), std::uint8_t(v * 40), std::uint8_t(128), std::uint8_t(7)}) bin.push_back(c);
    }
    for (std::uint16_t i : {2, 1, 0}) bin.push_back(std::uint8_t(i)), bin.push_back(0);
  }
  std::string json(const std::string& acc, const std::string& extra = "") const {
    return R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":)" + std::to_string(bin.size()) +
           R"(}],"bufferViews":[{"buffer":0,"byteLength":96,"byteStride":16},{"buffer":0,"byteOffset":96,"byteLength":6}],)"
           R"("accessors":[)" + acc + R"(],"meshes":[{"primitives":[{"attributes":{"POSITION":0,"COLOR_0":1},"indices":2},)"
           R"({"attributes":{"POSITION":0,"COLOR_0":1}}]}])" + extra + "}";
  }
};

}  // namespace

TEST_CASE("a .glb from another writer (interleaved, byte colours, shared vertices) reads, and bad ones are refused", "[gltf][errors]") {
  const TwoPrimitives t;
  const Mesh m = parseGlb(glbOf(t.json(t.accessors), t.bin));
  CHECK(m.vertexCount() == 6);  // the second primitive's vertices are the first's
  CHECK(m.indices == std::vector<std::uint32_t>{2, 1, 0, 0, 1, 2, 3, 4, 5});
  CHECK(m.positions[3 * 5 + 0] == 1.0f);
  CHECK(m.positions[3 * 5 + 2] == 1.0f);
  // Normalized bytes are linear light: 255 -> 255, 128/255 -> sRGB 188, v*40/255 encoded.
  CHECK(m.color(0) == Rgb8{255, 0, 188});
  CHECK(m.color(1) == Rgb8{255, linearToSrgb(40 / 255.0), 188});

  auto withAccessors = [&](const std::string& acc) { return glbError(glbOf(t.json(acc), t.bin)); };
  CHECK_THAT(withAccessors(R"({"bufferView":0,"componentType":5126,"count":7,"type":"VEC3"},)"
                           R"({"bufferView":0,"byteOffset":12,"componentType":5121,"normalized":true,"count":6,"type":"VEC4"},)"
                           R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"})"),
             Catch::Contains("accessor 0: its 7 elements do not fit in its bufferView"));
  CHECK_THAT(withAccessors(R"({"bufferView":0,"componentType":5126,"count":6,"type":"VEC3"},)"
                           R"({"bufferView":0,"byteOffset":12,"componentType":5121,"count":6,"type":"VEC4"},)"
                           R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"})"),
             Catch::Contains("COLOR_0 must be float or normalized"));
  CHECK_THAT(withAccessors(R"({"bufferView":0,"componentType":5126,"count":6,"type":"VEC3"},)"
                           R"({"bufferView":0,"byteOffset":12,"componentType":5121,"normalized":true,"count":6,"type":"VEC4"},)"
                           R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR","sparse":{}})"),
             Catch::Contains("sparse accessors are not read"));
  CHECK_THAT(withAccessors(R"({"bufferView":0,"componentType":5126,"count":6,"type":"VEC3"},)"
                           R"({"bufferView":0,"byteOffset":12,"componentType":5121,"normalized":true,"count":6,"type":"VEC4"},)"
                           R"({"bufferView":1,"componentType":5125,"count":3,"type":"SCALAR"})"),
             Catch::Contains("accessor 2: its 3 elements do not fit in its bufferView"));
  std::vector<std::uint8_t> badIndex = t.bin;
  badIndex[96] = 6;  // index 6 of 6 vertices
  CHECK_THAT(glbError(glbOf(t.json(t.accessors), badIndex)), Catch::Contains("glTF index 6 out of range"));
  std::vector<std::uint8_t> nan = t.bin;
  le::put32(nan.data() + 4, 0x7FC00000u);
  CHECK_THAT(glbError(glbOf(t.json(t.accessors), nan)), Catch::Contains("glTF vertex 0: coordinate is not finite"));

  // The document itself.
  CHECK_THAT(glbError(glbOf(t.json(t.accessors) + "x", t.bin)), Catch::Contains("text after the document"));
  CHECK_THAT(glbError(glbOf(std::string(100, '[') + std::string(100, ']'), t.bin)), Catch::Contains("nested too deeply"));
  CHECK_THAT(glbError(glbOf(R"({"meshes":[{"primitives":[{"mode":1,"attributes":{"POSITION":0}}]}]})", t.bin)),
             Catch::Contains("only triangles (4) are read"));
  CHECK_THAT(glbError(glbOf(R"({"buffers":[{"uri":"x.bin","byteLength":4}],"meshes":[]})", t.bin)),
             Catch::Contains("external file"));
  CHECK_THAT(glbError(glbOf(R"({"meshes":[]})", {})), Catch::Contains("glTF has no meshes"));
  std::vector<std::uint8_t> whole = glbOf(t.json(t.accessors), t.bin);
  for (std::size_t keep = 0; keep < whole.size(); keep += 7) {
    INFO(keep);
    CHECK(glbError(std::vector<std::uint8_t>(whole.begin(), whole.begin() + std::ptrdiff_t(keep))) != "read");
  }
  // A document that reads one accessor again and again: more bytes than the chunk holds.
  std::string many = R"({"buffers":[{"byteLength":)" + std::to_string(t.bin.size()) +
                     R"(}],"bufferViews":[{"buffer":0,"byteLength":96,"byteStride":16},{"buffer":0,"byteOffset":96,"byteLength":6}],)"
                     R"("accessors":[)" + t.accessors + R"(],"meshes":[{"primitives":[)";
  for (int i = 0; i < 40; ++i) many += std::string(i ? "," : "") + R"({"attributes":{"POSITION":0},"indices":2})";
  many += "]}]}";
  CHECK_THAT(glbError(glbOf(many, t.bin)), Catch::Contains("read more bytes than the binary chunk holds"));
}
