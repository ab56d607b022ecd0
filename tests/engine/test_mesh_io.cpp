#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "engine/errors.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

namespace {

using Corner = std::array<float, 3>;
using Triangle = std::array<Corner, 3>;

// The triangles as corner positions, whatever the vertex numbering.
std::vector<Triangle> triangles(const Mesh& m) {
  std::vector<Triangle> out;
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    Triangle tri;
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a)
        tri[std::size_t(k)][std::size_t(a)] = m.positions[3 * m.indices[3 * t + std::size_t(k)] + std::size_t(a)];
    out.push_back(tri);
  }
  return out;
}

std::span<const std::uint8_t> bytesOf(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// Message of the Format error that f throws ("" when it throws nothing or something else).
template <class F>
std::string formatError(F&& f) {
  try {
    f();
  } catch (const EngineError& e) {
    return e.kind() == ErrorKind::Format ? std::string(e.what()) : std::string();
  }
  return {};
}

Mesh tetrahedron() {
  Mesh m;
  m.positions = {2, 2, 2, 12, 2, 2, 2, 12, 2, 2, 2, 12};
  m.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

const Vec3 kCentre{35.3, 36.1, 34.7};
constexpr double kRadius = 30;

const Mesh& sphereMesh() {
  static const Mesh m = extractMesh(makeSphere({72, 72, 72}, kCentre, kRadius));
  return m;
}

}  // namespace

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
    for (const MeshFormat f : {MeshFormat::Stl, MeshFormat::Obj, MeshFormat::Ply}) {
      try {
        parseMesh(b, f);
      } catch (const EngineError& e) {
        CHECK(e.kind() == ErrorKind::Format);
      }
    }
  }
}

TEST_CASE("a sphere mesh imports as its signed distance field", "[mesh]") {
  const Mesh& m = sphereMesh();
  const Volume vol = importMesh(m, {72, 72, 72});
  double worst = 0;
  std::size_t bandVoxels = 0, wrongSign = 0;
  for (int z = 0; z < 72; ++z)
    for (int y = 0; y < 72; ++y)
      for (int x = 0; x < 72; ++x) {
        const double exact = length(Vec3{double(x), double(y), double(z)} - kCentre) - kRadius;
        const float d = vol.at(x, y, z);
        if (std::fabs(exact) > 0.05 && (d < 0) != (exact < 0)) ++wrongSign;
        if (std::fabs(exact) < vol.band() - 0.05) {
          ++bandVoxels;
          worst = std::max(worst, std::fabs(d - exact));
        } else if (std::fabs(exact) > vol.band() + 0.05) {
          REQUIRE(std::fabs(d) == vol.band());
        }
      }
  INFO("max distance error " << worst << " vu over " << bandVoxels << " band voxels");
  CHECK(bandVoxels > 50000);
  CHECK(worst < 0.05);
  CHECK(wrongSign == 0);

  // And the mesh of the imported field is the same sphere again.
  const Mesh again = extractMesh(vol);
  CHECK(eulerCharacteristic(again) == 2);
  CHECK(meshVolume(again) == Approx(meshVolume(m)).epsilon(0.002));
}

TEST_CASE("mesh import is independent of threads, orientation and vertex sharing", "[mesh]") {
  const Mesh m = extractMesh(makeSolid(SolidKind::Torus, {48, 48, 48}));
  ThreadPool pool(3);
  const Volume a = importMesh(m, {48, 48, 48}, 3.0f);
  CHECK(digest(importMesh(m, {48, 48, 48}, 3.0f, pool)) == digest(a));
  CHECK(countComponents(a) == 1);

  Mesh flipped = m;  // inside out: flipped back
  for (std::size_t t = 0; t < flipped.triangleCount(); ++t)
    std::swap(flipped.indices[3 * t + 1], flipped.indices[3 * t + 2]);
  CHECK(digest(importMesh(flipped, {48, 48, 48}, 3.0f)) == digest(a));

  CHECK(digest(importMesh(parseStl(exportStl(m)), {48, 48, 48}, 3.0f)) == digest(a));
}

TEST_CASE("a mesh covering the domain's first voxel fills it", "[mesh]") {
  Mesh cube = parseObj(
      "v -10 -10 -10\nv 40 -10 -10\nv 40 40 -10\nv -10 40 -10\nv -10 -10 40\nv 40 -10 40\nv 40 40 40\nv -10 40 40\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const Volume inside = importMesh(cube, {24, 24, 24});
  CHECK(inside.at(0, 0, 0) == -inside.band());
  CHECK(inside.at(23, 23, 23) == -inside.band());
  CHECK(inside.presentBricks() == 0);

  const Volume placed = importMesh(fitMeshToDomain(cube, {32, 32, 32}, 4), {32, 32, 32});
  CHECK(placed.at(0, 0, 0) == placed.band());
  CHECK(placed.at(4, 16, 16) == Approx(0).margin(1e-5));
  CHECK(placed.at(10, 16, 16) == -placed.band());
  CHECK(insideVolume(placed) == Approx(23.0 * 23 * 23).epsilon(0.01));
}

TEST_CASE("open, non-manifold and empty meshes are refused", "[mesh][errors]") {
  Mesh open = sphereMesh();
  open.indices.resize(open.indices.size() - 3);
  const std::string msg = formatError([&] { importMesh(open, {72, 72, 72}); });
  CHECK(msg.find("not closed: 3 edges") != std::string::npos);

  Mesh doubled = tetrahedron();
  const Mesh t2 = tetrahedron();
  doubled.indices.insert(doubled.indices.end(), t2.indices.begin(), t2.indices.begin() + 3);
  doubled.indices.insert(doubled.indices.end(), {0, 1, 2});
  CHECK(formatError([&] { importMesh(doubled, {16, 16, 16}); }).find("not manifold") != std::string::npos);

  Mesh twisted = tetrahedron();
  std::swap(twisted.indices[1], twisted.indices[2]);
  CHECK(formatError([&] { importMesh(twisted, {16, 16, 16}); }).find("consistently oriented") != std::string::npos);

  CHECK(formatError([&] { importMesh(Mesh{}, {16, 16, 16}); }).find("no triangles") != std::string::npos);
  Mesh bad = tetrahedron();
  bad.indices[4] = 9;
  CHECK(formatError([&] { importMesh(bad, {16, 16, 16}); }).find("out of range") != std::string::npos);
  Mesh nan = tetrahedron();
  nan.positions[5] = std::nanf("");
  CHECK(formatError([&] { importMesh(nan, {16, 16, 16}); }).find("not finite") != std::string::npos);
  CHECK_THROWS_AS(importMesh(tetrahedron(), {4, 16, 16}), EngineError);
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

TEST_CASE("an imported solid that fills the domain's partial edge bricks stores none of them", "[mesh]") {
  // A box from -20 to 14.5 on every axis in a 12^3 domain: every voxel is more than the band
  // inside, so the field is uniformly inside. The bricks at 8..15 are partial (voxels 8..11 in
  // the domain) and lie within reach of the box's faces at 14.5.
  Mesh cube = parseObj(
      "v -20 -20 -20\nv 14.5 -20 -20\nv 14.5 14.5 -20\nv -20 14.5 -20\nv -20 -20 14.5\nv 14.5 -20 14.5\n"
      "v 14.5 14.5 14.5\nv -20 14.5 14.5\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const Volume v = importMesh(cube, {12, 12, 12});
  CHECK(v.at(11, 11, 11) == -v.band());
  Volume full({12, 12, 12});
  full.fill(true);
  CHECK(v.presentBricks() == 0);
  CHECK(digest(v) == digest(full));
}
