#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "engine/marching_cubes.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "support.hpp"

using namespace marzipan;

namespace {

struct SphereError {
  double position = 0;  // largest | |p - c| - r | over the vertices
  double normal = 0;    // largest angle (radians) between a vertex normal and the radial direction
};

SphereError sphereError(const Mesh& m, Vec3 c, double r) {
  SphereError e;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const Vec3 d = m.position(v) - c;
    e.position = std::max(e.position, std::fabs(length(d) - r));
    e.normal = std::max(e.normal, std::acos(std::clamp(dot(normalized(d), m.normal(v)), -1.0, 1.0)));
  }
  return e;
}

bool sameMesh(const Mesh& a, const Mesh& b) {
  return a.positions == b.positions && a.normals == b.normals && a.indices == b.indices;
}

}  // namespace

TEST_CASE("the mesh of a sphere of radius 30 is a closed outward sphere", "[mesh][mc]") {
  const Vec3 c{35.3, 36.1, 34.7};
  const double r = 30;
  const Volume vol = makeSphere({72, 72, 72}, c, r);
  const Mesh m = extractMesh(vol);
  REQUIRE(m.triangleCount() > 10000);
  REQUIRE(m.normals.size() == m.positions.size());

  const EdgeCheck edges = checkEdges(m);
  CHECK(edges.boundary == 0);
  CHECK(edges.nonManifold == 0);
  CHECK(edges.misoriented == 0);
  CHECK(edges.degenerate == 0);
  CHECK(eulerCharacteristic(m) == 2);

  const SphereError err = sphereError(m, c, r);
  INFO("max vertex error " << err.position << " vu, max normal error " << err.normal << " rad");
  CHECK(err.position < 0.05);
  CHECK(err.normal < 0.05);

  const double exact = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  CHECK(meshVolume(m) > 0);
  CHECK(std::fabs(meshVolume(m) - exact) < 0.01 * exact);
  CHECK(std::fabs(meshArea(m) - 4 * std::numbers::pi * r * r) < 0.01 * 4 * std::numbers::pi * r * r);
}

TEST_CASE("every vertex sits on its own crossed grid edge", "[mesh][mc]") {
  const Mesh m = extractMesh(makeSphere({48, 48, 48}, {23.6, 24.2, 22.9}, 15));
  // A vertex has two integer coordinates; no two vertices share a position.
  std::vector<std::array<float, 3>> seen;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    int integral = 0;
    for (int a = 0; a < 3; ++a)
      integral += m.positions[3 * v + std::size_t(a)] == std::floor(m.positions[3 * v + std::size_t(a)]);
    REQUIRE(integral >= 2);
    seen.push_back({m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]});
  }
  std::sort(seen.begin(), seen.end());
  CHECK(std::adjacent_find(seen.begin(), seen.end()) == seen.end());
}

TEST_CASE("the torus has Euler characteristic 0", "[mesh][mc]") {
  const Mesh m = extractMesh(makeSolid(SolidKind::Torus, {96, 96, 96}));
  CHECK(checkEdges(m).closedManifold());
  CHECK(eulerCharacteristic(m) == 0);
  CHECK(meshVolume(m) > 0);
}

TEST_CASE("spheres cut by brick boundaries have no cracks", "[mesh][mc]") {
  // Centred on brick corners and edges, small enough that every cell straddles a boundary.
  for (const Vec3 c : {Vec3{16, 16, 16}, Vec3{15.5, 16.25, 24}, Vec3{23.99, 8.01, 16.5}}) {
    for (const double r : {1.3, 3.7, 7.9}) {
      const Mesh m = extractMesh(makeSphere({40, 40, 40}, c, r));
      INFO("centre " << c.x << "," << c.y << "," << c.z << " radius " << r);
      CHECK(checkEdges(m).closedManifold());
      CHECK(eulerCharacteristic(m) == 2);
      CHECK(meshVolume(m) > 0);
    }
  }
}

TEST_CASE("a solid cut by the domain's sides is capped there", "[mesh][mc]") {
  for (const Vec3 c : {Vec3{0, 20, 20}, Vec3{39, 39, 0.5}}) {
    const Mesh m = extractMesh(makeSphere({40, 40, 40}, c, 12));
    CHECK(checkEdges(m).closedManifold());
    CHECK(eulerCharacteristic(m) == 2);
    CHECK(meshVolume(m) > 0);
  }
  Volume full({24, 16, 8});
  full.fill(true);
  const Mesh box = extractMesh(full);
  CHECK(checkEdges(box).closedManifold());
  CHECK(eulerCharacteristic(box) == 2);
  // The faces sit half-way between the last inside voxel and the air beyond the domain; each
  // box edge is chamfered by a right prism of legs 0.5 (the corners give back a little).
  const double chamfered = 24.0 * 16 * 8 - 0.125 * 4 * (24 + 16 + 8);
  CHECK(meshVolume(box) > chamfered);
  CHECK(meshVolume(box) < chamfered + 1);
}

TEST_CASE("noise fields, full of ambiguous cells, still give closed manifold meshes", "[mesh][mc]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> value(-3, 3);
  for (int round = 0; round < 4; ++round) {
    Volume vol({24, 20, 17});
    const Box b = vol.domain();
    std::vector<float> v(std::size_t(b.voxels()));
    for (auto& x : v) x = value(rng);
    vol.scatter(b, v.data(), b);
    const Mesh m = extractMesh(vol);
    const EdgeCheck e = checkEdges(m);
    INFO("round " << round << ": " << e.boundary << " boundary, " << e.nonManifold << " non-manifold, " << e.misoriented
                  << " misoriented edges, " << e.degenerate << " degenerate triangles");
    CHECK(e.closedManifold());
    CHECK(meshVolume(m) > 0);
  }
}

TEST_CASE("an empty volume has an empty mesh", "[mesh][mc]") {
  const Mesh m = extractMesh(Volume({32, 32, 32}));
  CHECK(m.vertexCount() == 0);
  CHECK(m.triangleCount() == 0);
  CHECK(eulerCharacteristic(m) == 0);
}

TEST_CASE("the mesh is identical for any thread count", "[mesh][mc]") {
  const Volume vol = makeSolid(SolidKind::Dumbbell, {80, 64, 64});
  ThreadPool pool(3);
  const Mesh serial = extractMesh(vol);
  const Mesh parallel = extractMesh(vol, pool);
  CHECK(sameMesh(serial, parallel));
  CHECK(checkEdges(serial).closedManifold());
}

// Texels that are a linear function of the voxel (4x, 4y, 4z): their trilinear mix at a vertex
// is 4 times its position, each channel rounded to the nearest byte.
TEST_CASE("vertex colours are the trilinear mix of the voxels' colours at the vertex", "[marching_cubes][color]") {
  Volume vol = makeSphere({64, 64, 64}, {31.3, 30.6, 32.2}, 20);
  test::paintBricks(vol, [](Int3 b, int i) {
    const Int3 p = Bricks::origin(b) + Bricks::local(i);
    return Texel{std::uint8_t(4 * p.x), std::uint8_t(4 * p.y), std::uint8_t(4 * p.z), 0};
  });
  REQUIRE(vol.paintedBricks() > 0);
  ThreadPool pool(2);
  const Mesh m = extractMesh(vol, pool);
  REQUIRE(m.colors.size() == m.positions.size());
  std::size_t wrong = 0;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const Vec3 p = m.position(v);
    const Rgb8 want{std::uint8_t(std::lround(4 * p.x)), std::uint8_t(std::lround(4 * p.y)),
                    std::uint8_t(std::lround(4 * p.z))};
    wrong += m.color(v) == want ? 0 : 1;
  }
  CHECK(wrong == 0);
  CHECK(extractMesh(vol).colors == m.colors);
}

TEST_CASE("a volume that carries no colour gives no vertex colours, a base colour gives it everywhere",
          "[marching_cubes][color]") {
  Volume vol = makeSphere({32, 32, 32}, {15.5, 16.2, 15.8}, 9);
  CHECK_FALSE(carriesColor(vol));
  CHECK(extractMesh(vol).colors.empty());

  // Painted, then painted back to the base colour: nothing carried, as never painted.
  test::paintBricks(vol, [](Int3, int) { return Texel{1, 2, 3, 0}; });
  CHECK(carriesColor(vol));
  test::paintBricks(vol, [](Int3, int) { return texelOf(kClayColor); });
  CHECK_FALSE(carriesColor(vol));
  CHECK(extractMesh(vol).colors.empty());

  Volume blue = makeSphere({32, 32, 32}, {15.5, 16.2, 15.8}, 9);
  blue.setBaseColor({10, 20, 250});
  const Mesh m = extractMesh(blue);
  REQUIRE(m.colors.size() == m.positions.size());
  for (std::size_t v = 0; v < m.vertexCount(); ++v) REQUIRE(m.color(v) == Rgb8{10, 20, 250});
}
