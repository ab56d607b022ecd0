// Wall thickness on shapes whose thickness is known exactly: a slab, a spherical shell and a
// thin cylinder (its diameter seen from the side).
#include <catch2/catch.hpp>

#include <cmath>

#include "engine/errors.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "engine/thickness.hpp"

using namespace marzipan;

TEST_CASE("a slab is as thick as it is, wherever it is measured", "[thickness]") {
  // 3 vu thick in y, wide in x and z.
  const Volume slab = makeBox({64, 64, 64}, {32, 32.3, 32}, {24, 1.5, 24});
  for (const double x : {20.0, 31.7, 40.2}) {
    CHECK(thicknessAt(slab, {x, 33.8, 30}, {0, 1, 0}) == Approx(3.0).margin(0.02));
    CHECK(thicknessAt(slab, {x, 30.8, 30}, {0, -1, 0}) == Approx(3.0).margin(0.02));
  }
  const ThicknessReport r = analyzeThickness(slab, 4.0);
  CHECK(r.thinnest == Approx(3.0).margin(0.1));
  // The big faces are thinner than 4 vu; the 48 x 48 faces hold most of the surface.
  CHECK(r.below > r.points / 2);
  REQUIRE_FALSE(r.places.empty());
  CHECK(r.places.front().thickness == Approx(r.thinnest));
  for (std::size_t i = 1; i < r.places.size(); ++i) CHECK(r.places[i].thickness >= r.places[i - 1].thickness);
  CHECK(analyzeThickness(slab, 2.5).below == 0);
}

TEST_CASE("a spherical shell is R1 - R2 thick", "[thickness]") {
  const Vec3 c{40, 40, 40};
  const Volume shell = makeFromFunction(
      {80, 80, 80}, [&](Vec3 p) { return std::max(sdf::sphere(p, c, 30), -sdf::sphere(p, c, 26)); }, true);
  double worst = 0;
  for (const Vec3 dir : {Vec3{1, 0, 0}, normalized(Vec3{1, 1, 0}), normalized(Vec3{0.3, -0.5, 0.8}), Vec3{0, 0, -1}}) {
    worst = std::max(worst, std::fabs(thicknessAt(shell, c + dir * 30, dir) - 4));
    worst = std::max(worst, std::fabs(thicknessAt(shell, c + dir * 26, dir * -1.0) - 4));
  }
  INFO("worst error " << worst << " vu");
  CHECK(worst < 0.05);
  const ThicknessReport r = analyzeThickness(shell, 5.0);
  CHECK(r.below == r.points);  // the whole shell is thinner than 5 vu
  CHECK(r.thinnest == Approx(4.0).margin(0.1));
  CHECK(analyzeThickness(shell, 3.8).below == 0);
}

TEST_CASE("a thin cylinder is its diameter thick from the side", "[thickness]") {
  const Volume rod = makeFromFunction(
      {48, 64, 48}, [](Vec3 p) { return sdf::cylinder(p, {24, 32, 24}, 2.0, 24, 1); }, true);
  // Radius 2 vu: the trilinear interpolant of the samples rounds the circle off between voxels
  // by up to ~0.1 vu across a diagonal chord; along the axes it is exact.
  CHECK(thicknessAt(rod, Vec3{26, 30, 24}, {1, 0, 0}) == Approx(4.0).margin(0.02));
  for (const Vec3 dir : {normalized(Vec3{1, 0, 1}), normalized(Vec3{-0.6, 0, 0.8})})
    CHECK(thicknessAt(rod, Vec3{24, 30, 24} + dir * 2.0, dir) == Approx(4.0).margin(0.15));
  // Along its axis, from an end cap: the length.
  CHECK(thicknessAt(rod, {24, 56, 24}, {0, 1, 0}) == Approx(48.0).margin(0.05));
  const ThicknessReport r = analyzeThickness(rod, 5.0, 8, 4, ThreadPool::serial());
  REQUIRE(r.below > 0);
  CHECK(r.places.size() == 8);
  for (const ThinPlace& q : r.places) {
    CHECK(q.thickness < 5.0);
    CHECK(std::fabs(q.normal.y) < 0.5);  // on the side, not a cap
  }
  ThreadPool two(2);
  const ThicknessReport r2 = analyzeThickness(rod, 5.0, 8, 4, two);
  CHECK(r2.below == r.below);
  CHECK(r2.places.front().thickness == r.places.front().thickness);
  CHECK_THROWS_AS(analyzeThickness(rod, 0.0), EngineError);
  CHECK_THROWS_AS(analyzeThickness(rod, std::nan("")), EngineError);
  CHECK(analyzeThickness(makeSolid(SolidKind::Empty, {16, 16, 16}), 1.0).points == 0);
}
