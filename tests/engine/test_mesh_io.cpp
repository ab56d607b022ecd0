#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "engine/errors.hpp"
#include "engine/little_endian.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "mesh_support.hpp"
#include "test_paths.hpp"

using namespace marzipan;
using namespace marzipan::test;

TEST_CASE("STL, OBJ and PLY exports parse back to the same triangles", "[mesh]") {
  const Mesh m = extractMesh(makeSphere({32, 32, 32}, {15.2, 16.7, 15.9}, 9));
  REQUIRE(m.triangleCount() > 1000);

  const auto stl = exportStl(m);
  CHECK(stl.size() == 84 + 50 * m.triangleCount());
  const Mesh fromStl = parseStl(stl);
  CHECK(triangles(fromStl) == triangles(m));
  CHECK(fromStl.vertexCount() == m.vertexCount());  // corners are merged back into vertices
  CHECK(checkEdges(fromStl).closedManifold());

  const std::string obj = exportObj(m);
  CHECK(obj.find("\nf 1//1 ") != std::string::npos);
  const Mesh fromObj = parseObj(obj);
  CHECK(fromObj.positions == m.positions);
  CHECK(fromObj.normals == m.normals);
  CHECK(fromObj.indices == m.indices);

  const auto ply = exportPly(m);
  const Mesh fromPly = parsePly(ply);
  CHECK(fromPly.positions == m.positions);
  CHECK(fromPly.normals == m.normals);
  CHECK(fromPly.indices == m.indices);

  for (const MeshFormat f : {MeshFormat::Stl, MeshFormat::Obj, MeshFormat::Ply})
    CHECK(triangles(parseMesh(exportMesh(m, f), f)) == triangles(m));
}

TEST_CASE("files are written whole", "[mesh]") {
  const auto path = (std::filesystem::temp_directory_path() / "marzipan_test_mesh.stl").string();
  const auto stl = exportStl(tetrahedron());
  writeFile(path, stl);
  std::ifstream f(path, std::ios::binary);
  const std::vector<std::uint8_t> back((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  CHECK(back == stl);
  std::filesystem::remove(path);
  CHECK_THROWS_AS(writeFile("/nonexistent-dir/x.stl", stl), EngineError);
}

TEST_CASE("ASCII STL and polygonal OBJ files parse", "[mesh]") {
  const std::string ascii =
      "solid tet\n"
      " facet normal 0 0 -1\n  outer loop\n   vertex 2 2 2\n   vertex 2 12 2\n   vertex 12 2 2\n  endloop\n endfacet\n"
      " facet normal 0 -1 0\n  outer loop\n   vertex 2 2 2\n   vertex 12 2 2\n   vertex 2 2 12\n  endloop\n endfacet\n"
      " facet normal -1 0 0\n  outer loop\n   vertex 2 2 2\n   vertex 2 2 12\n   vertex 2 12 2\n  endloop\n endfacet\n"
      " facet normal 1 1 1\n  outer loop\n   vertex 12 2 2\n   vertex 2 12 2\n   vertex +2e0 2 1.2E1\n  endloop\n "
      "endfacet\n"
      "endsolid tet\n";
  const Mesh m = parseStl(bytesOf(ascii));
  CHECK(m.vertexCount() == 4);
  CHECK(m.triangleCount() == 4);
  CHECK(checkEdges(m).closedManifold());
  CHECK(meshVolume(m) == Approx(1000.0 / 6));

  // A cube of quads, with relative indices, texture coordinates and comments.
  const std::string obj =
      "# cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nvt 0 0\n"
      "f 1/1 4/1 3/1 2/1\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf -4 -1 -5 -8\n";
  const Mesh cube = parseObj(obj);
  CHECK(cube.triangleCount() == 12);
  CHECK(cube.normals.empty());
  CHECK(checkEdges(cube).closedManifold());
  CHECK(meshVolume(cube) == Approx(1.0));
}

TEST_CASE("every truncated prefix of a binary STL is rejected", "[mesh]") {
  const auto stl = exportStl(extractMesh(makeSphere({16, 16, 16}, {7.6, 8.2, 7.9}, 4)));
  REQUIRE(stl.size() > 2000);
  for (std::size_t n = 0; n < stl.size(); ++n) {
    const std::string msg = formatError([&] { parseStl(std::span(stl.data(), n)); });
    INFO("prefix of " << n << " bytes");
    REQUIRE(!msg.empty());
  }
  CHECK(formatError([&] { parseStl(std::span(stl.data(), 100)); }).find("truncated") != std::string::npos);
}

TEST_CASE("malformed mesh files are rejected with a clear message", "[mesh][errors]") {
  auto stlError = [](std::vector<std::uint8_t> b) { return formatError([&] { parseStl(b); }); };
  CHECK(stlError({}).find("empty") != std::string::npos);

  // A header that promises four billion triangles over a few bytes: no allocation, an error.
  std::vector<std::uint8_t> absurd(84 + 50, 0);
  std::memset(absurd.data() + 80, 0xFF, 4);
  CHECK(stlError(absurd).find("does not match") != std::string::npos);
  std::vector<std::uint8_t> none(84, 0);
  CHECK(stlError(none).find("no triangles") != std::string::npos);

  auto nanStl = exportStl(tetrahedron());
  const float nan = std::nanf("");
  std::memcpy(nanStl.data() + 84 + 12, &nan, 4);
  CHECK(stlError(nanStl).find("not finite") != std::string::npos);

  CHECK(stlError({'s', 'o', 'l', 'i', 'd', ' ', 'x', '\n', 'f', 'a', 'c', 'e', 't'}).find("ends before") !=
        std::string::npos);
  const std::string badVertex = "solid\nfacet normal 0 0 1\nouter loop\nvertex 1 2 x\n";
  CHECK(formatError([&] { parseStl(bytesOf(badVertex)); }).find("line 4") != std::string::npos);

  auto objError = [](const std::string& s) { return formatError([&] { parseObj(s); }); };
  CHECK(objError("").find("no faces") != std::string::npos);
  CHECK(objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").find("out of range") != std::string::npos);
  CHECK(objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").find("bad index") != std::string::npos);
  CHECK(objError("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n").find("at least 3") != std::string::npos);
  CHECK(objError("v 0 nan 0\n").find("line 1: coordinate is not finite") != std::string::npos);
  CHECK(objError("v 0 0\n").find("three coordinates") != std::string::npos);
  CHECK(objError("v 0 0 0\nf -2 1 1\n").find("relative index") != std::string::npos);

  auto plyError = [](const std::string& s) { return formatError([&] { parsePly(bytesOf(s)); }); };
  CHECK(plyError("solid").find("does not start") != std::string::npos);
  CHECK(plyError("ply\nformat ascii 1.0\nend_header\n").find("binary_little_endian") != std::string::npos);
  CHECK(plyError("ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                 "property float y\nproperty float z\nend_header\n")
            .find("truncated") != std::string::npos);
  const auto ply = exportPly(tetrahedron());
  for (std::size_t n = 0; n < ply.size(); ++n) {
    INFO("PLY prefix of " << n << " bytes");
    REQUIRE(!formatError([&] { parsePly(std::span(ply.data(), n)); }).empty());
  }
}

TEST_CASE("garbage bytes never crash the parsers", "[mesh][errors]") {
  std::mt19937 rng(3);
  for (int round = 0; round < 200; ++round) {
    std::vector<std::uint8_t> b(std::size_t(rng() % 400));
    for (auto& x : b) x = std::uint8_t(rng());
    if (round % 2 && b.size() >= 84) {  // a size that matches its count: a binary STL of junk
      const std::uint32_t count = std::uint32_t((b.size() - 84) / 50);
      b.resize(84 + 50 * count);
      std::memcpy(b.data() + 80, &count, 4);
    }
    for (const MeshFormat f : {MeshFormat::Stl, MeshFormat::Obj, MeshFormat::Ply, MeshFormat::Glb}) {
      try {
        parseMesh(b, f);
      } catch (const EngineError& e) {
        CHECK(e.kind() == ErrorKind::Format);
      }
    }
  }
}

TEST_CASE("PLY normals out of float range are refused, not converted", "[mesh][errors]") {
  // One triangle with double normals; the second vertex's nx is 1e300, beyond any float.
  std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nproperty double nx\nproperty double ny\nproperty double nz\n"
      "element face 1\nproperty list uchar uint vertex_indices\nend_header\n";
  std::vector<std::uint8_t> b(header.begin(), header.end());
  auto add = [&](const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b.insert(b.end(), c, c + n);
  };
  const float pos[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (int v = 0; v < 3; ++v) {
    add(pos[v], 12);
    const double n[3] = {v == 1 ? 1e300 : 0.0, 0.0, 1.0};
    add(n, 24);
  }
  const std::uint8_t count = 3;
  const std::uint32_t idx[3] = {0, 1, 2};
  add(&count, 1);
  add(idx, 12);
  CHECK(formatError([&] { parsePly(b); }).find("not finite") != std::string::npos);
}


namespace {

// A binary PLY of one triangle: `header` between the format line and end_header, then `body`.
std::vector<std::uint8_t> plyFile(const std::string& header, const std::vector<std::uint8_t>& body) {
  const std::string text = "ply\nformat binary_little_endian 1.0\n" + header + "end_header\n";
  std::vector<std::uint8_t> b(text.begin(), text.end());
  b.insert(b.end(), body.begin(), body.end());
  return b;
}
template <class T>
void put(std::vector<std::uint8_t>& b, T v) {
  const auto* c = reinterpret_cast<const std::uint8_t*>(&v);
  b.insert(b.end(), c, c + sizeof v);
}
std::vector<std::uint8_t> oneFace() {
  std::vector<std::uint8_t> b;
  put(b, std::uint8_t(3));
  for (const std::uint32_t i : {0u, 1u, 2u}) put(b, i);
  return b;
}

}  // namespace

TEST_CASE("a PLY header that repeats its format line, an element or a property is refused", "[mesh][errors]") {
  // The fuzzer's find (tests/fuzz/regressions/ply/): the preamble again inside the header, so
  // a second vertex element without normals' match. Read as two, it gave 288 positions and 144
  // normals, which no exporter can take.
  std::ifstream in(std::string(marzipan::test_paths::kFuzzRegressions) + "/ply/repeated-preamble-second-vertex-element.ply",
                   std::ios::binary);
  REQUIRE(in);
  const std::vector<std::uint8_t> found{std::istreambuf_iterator<char>(in), {}};
  CHECK(formatError([&] { parsePly(found); }).find("line 9: the format line is repeated") != std::string::npos);

  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string face = "element face 1\nproperty list uchar uint vertex_indices\n";
  auto plyError = [&](const std::string& header) { return formatError([&] { parsePly(plyFile(header, {})); }); };
  CHECK(plyError("element vertex 3\n" + xyz + "element vertex 3\n" + xyz + "property float nx\n" + face)
            .find("line 7: element \"vertex\" is repeated") != std::string::npos);
  CHECK(plyError("element vertex 3\n" + xyz + face + face).find("line 9: element \"face\" is repeated") !=
        std::string::npos);
  CHECK(plyError("element vertex 3\n" + xyz + "property float x\n" + face)
            .find("line 7: property \"x\" is repeated") != std::string::npos);
  CHECK(plyError("element vertex 3\nproperty float\n" + face).find("line 4: property has no name") !=
        std::string::npos);
}

TEST_CASE("PLY vertices of mixed scalar types, with properties after the normals, read exactly", "[mesh]") {
  // x float, y double, z short, then the normals as char, short and float, then a property
  // the reader does not use: each value lands where its own offset says.
  const std::string header =
      "element vertex 3\nproperty float x\nproperty double y\nproperty short z\nproperty char nx\n"
      "property short ny\nproperty float nz\nproperty uchar quality\n"
      "element face 1\nproperty list uchar uint vertex_indices\n";
  std::vector<std::uint8_t> body;
  const float xs[3] = {0.5f, 10.25f, 3.0f};
  const double ys[3] = {-1.5, 2.0, 12.75};
  const std::int16_t zs[3] = {-300, 7, 32000};
  for (int v = 0; v < 3; ++v) {
    put(body, xs[v]);
    put(body, ys[v]);
    put(body, zs[v]);
    put(body, std::int8_t(-1));
    put(body, std::int16_t(v));
    put(body, 0.5f * float(v));
    put(body, std::uint8_t(200));
  }
  const auto f = oneFace();
  body.insert(body.end(), f.begin(), f.end());
  const Mesh m = parsePly(plyFile(header, body));
  CHECK(m.positions == std::vector<float>{0.5f, -1.5f, -300, 10.25f, 2, 7, 3, 12.75f, 32000});
  CHECK(m.normals == std::vector<float>{-1, 0, 0, -1, 1, 0.5f, -1, 2, 1});
  CHECK(m.indices == std::vector<std::uint32_t>{0, 1, 2});
}

namespace {

std::uint64_t fnv1a(std::span<const std::uint8_t> bytes) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (const std::uint8_t b : bytes) h = (h ^ b) * 0x100000001b3ull;
  return h;
}

}  // namespace

// The hashes were taken from the files of commit e84f0fa, before meshes carried colour: a volume
// never painted must keep giving those very bytes.
TEST_CASE("a volume never painted exports the bytes it gave before meshes had colours", "[mesh][color]") {
  const Volume vol = makeSphere({32, 32, 32}, {15.2, 16.7, 15.9}, 9);
  const Mesh m = extractMesh(vol);
  CHECK(fnv1a(exportMesh(m, MeshFormat::Stl)) == 0x59114b66ac139649ull);
  CHECK(fnv1a(exportMesh(m, MeshFormat::Obj)) == 0xeb6b798455d5bde5ull);
  CHECK(fnv1a(exportMesh(m, MeshFormat::Ply)) == 0x8b5b3d736735fbcaull);
  CHECK(fnv1a(exportMesh(m, MeshFormat::Glb)) == 0x73dfbc045fdf6b47ull);
}

namespace {

// The sphere with vertex colours that are a function of the vertex index.
Mesh coloredSphere() {
  Mesh m = extractMesh(makeSphere({32, 32, 32}, {15.2, 16.7, 15.9}, 9));
  m.colors.resize(m.positions.size());
  for (std::size_t i = 0; i < m.colors.size(); ++i) m.colors[i] = std::uint8_t(i * 37 % 256);
  return m;
}

}  // namespace

TEST_CASE("PLY and OBJ vertex colours are written as MeshLab reads them and parse back exactly", "[mesh][color]") {
  const Mesh m = coloredSphere();
  const auto ply = exportPly(m);
  const std::string text(ply.begin(), ply.end());
  CHECK(text.find("property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face") !=
        std::string::npos);
  const Mesh fromPly = parsePly(ply);
  CHECK(fromPly.colors == m.colors);
  CHECK(fromPly.positions == m.positions);

  const std::string obj = exportObj(m);
  // Vertex 1's colour: bytes 0, 37, 74 as 0, 37/255 and 74/255 in 4 digits.
  std::string_view first(obj);
  first.remove_prefix(obj.find("\nv ") + 1);
  first = first.substr(0, first.find('\n'));
  CHECK(first.substr(first.size() - 16) == " 0 0.1451 0.2902");
  const Mesh fromObj = parseObj(obj);
  CHECK(fromObj.colors == m.colors);
  CHECK(fromObj.positions == m.positions);
  for (const MeshFormat f : {MeshFormat::Obj, MeshFormat::Ply}) CHECK(parseMesh(exportMesh(m, f), f).colors == m.colors);
}

TEST_CASE("PLY colours of other types, OBJ vertices with and without colours, and bad colours", "[mesh][color][errors]") {
  // Float colours in 0..1 and ushort ones in 0..255, with alpha and in another order.
  std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property float blue\nproperty ushort red\nproperty float green\nproperty uchar alpha\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::vector<std::uint8_t> ply(head.begin(), head.end());
  auto f32 = [&](float f) { le::appendF32(ply, f); };
  auto u16 = [&](std::uint16_t u) { ply.push_back(std::uint8_t(u)), ply.push_back(std::uint8_t(u >> 8)); };
  const float blues[3] = {0, 0.5f, 1}, greens[3] = {1, 0.2f, 0.0039f};
  const std::uint16_t reds[3] = {0, 128, 255};
  for (int v = 0; v < 3; ++v) {
    f32(float(v == 1)), f32(float(v == 2)), f32(0);
    f32(blues[v]), u16(reds[v]), f32(greens[v]), ply.push_back(200);
  }
  ply.push_back(3);
  for (std::uint32_t i : {0u, 1u, 2u}) le::append32(ply, i);
  const Mesh m = parsePly(ply);
  CHECK(m.colors == std::vector<std::uint8_t>{0, 255, 0, 128, 51, 128, 255, 1, 255});

  auto withRed = [&](std::uint16_t red) {
    std::vector<std::uint8_t> bad = ply;
    const std::size_t at = head.size() + 16;  // vertex 0's red
    bad[at] = std::uint8_t(red), bad[at + 1] = std::uint8_t(red >> 8);
    return formatError([&] { parsePly(bad); });
  };
  CHECK(withRed(255).empty());
  CHECK(withRed(256).find("vertex 0: colour outside 0..255") != std::string::npos);

  const std::string colored = "v 0 0 0 1 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 0.2 0.2 1\nf 1 2 3\n";
  CHECK(parseObj(colored).colors == std::vector<std::uint8_t>{255, 0, 128, 0, 255, 0, 51, 51, 255});
  // One vertex without colour (or with a w): the file's colours are not all there, none are kept.
  CHECK(parseObj("v 0 0 0 1 0 0.5\nv 1 0 0\nv 0 1 0 0.2 0.2 1\nf 1 2 3\n").colors.empty());
  CHECK(parseObj("v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n").colors.empty());
  CHECK(formatError([] { parseObj("v 0 0 0 1 0 1.5\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); })
            .find("line 1: a vertex colour must be three numbers in 0..1") != std::string::npos);
  CHECK(formatError([] { parseObj("v 0 0 0 1 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); })
            .find("line 1: a vertex colour") != std::string::npos);

  Mesh short3 = tetrahedron();
  short3.colors = {1, 2, 3};
  for (const MeshFormat f : {MeshFormat::Stl, MeshFormat::Obj, MeshFormat::Ply, MeshFormat::Glb})
    CHECK_THROWS_AS(exportMesh(short3, f), EngineError);
}
