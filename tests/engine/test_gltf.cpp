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
  CHECK_THROWS_AS(parseMesh(glb, MeshFormat::Glb), EngineError);
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
