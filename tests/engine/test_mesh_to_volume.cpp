#include <catch2/catch.hpp>

#include <cmath>
#include <string>

#include "engine/errors.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/mesh_to_volume.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "mesh_support.hpp"

using namespace marzipan;
using namespace marzipan::test;

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
