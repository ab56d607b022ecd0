#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/channels.hpp"
#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "support.hpp"

using namespace marzipan;

namespace {

// Largest |d - exact| at band voxels on the side where min/max of two distances is the exact
// distance (outside a union, inside an intersection or difference) and more than `crease` vu
// from where the two operands meet.
template <class Exact, class A, class B>
double errorAwayFromCrease(const Volume& v, Exact exact, A da, B db, double crease, int side) {
  double worst = 0;
  const Int3 n = v.dims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const Vec3 p{double(x), double(y), double(z)};
        const double e = exact(p);
        if (std::fabs(e) >= v.band() - 0.5 || std::fabs(da(p) - db(p)) < crease || e * side < 0) continue;
        worst = std::max(worst, std::fabs(v.at(x, y, z) - e));
      }
  return worst;
}

}  // namespace

TEST_CASE("add, subtract and intersect match analytic CSG away from creases", "[csg]") {
  const Int3 dims{64, 64, 64};
  const Vec3 c{30, 32, 32}, t{44, 33, 31};
  auto base = [&](Vec3 p) { return sdf::sphere(p, c, 15); };
  for (ToolShape shape : {ToolShape::Sphere, ToolShape::Box, ToolShape::Cylinder}) {
    CsgParams p;
    p.shape = shape;
    p.center = t;
    p.radius = 7;
    auto tool = [&](Vec3 x) { return toolDistance(p, x); };
    for (CsgOp op : {CsgOp::Add, CsgOp::Subtract, CsgOp::Intersect}) {
      p.op = op;
      Volume v = makeSphere(dims, c, 15);
      applyCsg(v, p);
      auto exact = [&](Vec3 x) {
        switch (op) {
          case CsgOp::Add: return std::min(base(x), tool(x));
          case CsgOp::Subtract: return std::max(base(x), -tool(x));
          default: return std::max(base(x), tool(x));
        }
      };
      auto other = [&](Vec3 x) { return op == CsgOp::Subtract ? -tool(x) : tool(x); };
      INFO("shape " << int(shape) << " op " << int(op));
      const int side = op == CsgOp::Add ? +1 : -1;
      CHECK(errorAwayFromCrease(v, exact, base, other, 2.0, side) <= 0.05);
      CHECK(test::strayBandVoxels(v) == 0);
    }
  }
}

TEST_CASE("constructive tools keep the gradient error small away from creases", "[csg]") {
  Volume v = makeSphere({64, 64, 64}, {30, 32, 32}, 15);
  CsgParams p;
  p.center = {44, 33, 31};
  p.radius = 7;
  applyCsg(v, p);
  // Away from the crease circle (where the spheres meet, x ~ 42) the field is a distance.
  CHECK(gradientError(v, {{0, 0, 0}, {36, 64, 64}}).max < 0.02);
  CHECK(gradientError(v, {{46, 0, 0}, {64, 64, 64}}).max < 0.02);
}

TEST_CASE("a smooth blend fills the crease", "[csg]") {
  Volume sharp = makeSphere({64, 64, 64}, {30, 32, 32}, 15);
  Volume smooth = sharp;
  CsgParams p;
  p.center = {44, 32, 32};
  p.radius = 7;
  applyCsg(sharp, p);
  p.blend = 4;
  applyCsg(smooth, p);
  // In the crease between the spheres the blend adds material; far from it nothing changes.
  const Vec3 crease{43.3, 32, 32 + 8.1};  // just outside the circle where the spheres meet
  CHECK(smooth.sample(crease) < sharp.sample(crease) - 0.3);
  CHECK(smooth.at(15, 32, 32) == sharp.at(15, 32, 32));
}

TEST_CASE("constructive tools refuse bad parameters and change nothing", "[csg][errors]") {
  Volume v = makeSphere({48, 48, 48}, {24, 24, 24}, 12);
  const std::uint64_t d0 = digest(v);
  CsgParams ok;
  ok.center = {30, 24, 24};
  ok.radius = 5;
  auto bad = [&](auto edit) {
    CsgParams p = ok;
    edit(p);
    CHECK_THROWS_AS(applyCsg(v, p), EngineError);
  };
  bad([](CsgParams& p) { p.center.x = std::nan(""); });
  bad([](CsgParams& p) { p.radius = -1; });
  bad([](CsgParams& p) { p.radius = HUGE_VAL; });
  bad([](CsgParams& p) { p.blend = -1; });
  bad([](CsgParams& p) { p.blend = 50; });
  bad([](CsgParams& p) { p.axis = 3; });
  bad([](CsgParams& p) { p.center = {500, 24, 24}; });
  bad([](CsgParams& p) { p.center = {500, 24, 24}; p.op = CsgOp::Intersect; });
  bad([](CsgParams& p) { p.center = {1e300, -1e300, 24}; });
  CHECK(digest(v) == d0);
  CHECK(toolShapeFromName("box") == ToolShape::Box);
  CHECK_FALSE(toolShapeFromName("cone").has_value());
}

// --- channels: a CSG tool's colour, and colour that follows the cut ---------------------------

namespace {

const Rgb8 kRed{200, 20, 10}, kBlue{20, 40, 210};

// Over every band voxel of v: how many lie where the tool's exact term beats the solid's by more
// than `margin` vu (`tool`, and how many of those do not read `inTool`), and where the solid's
// beats the tool's by more than that (`solid`, and how many do not read `inSolid`). The solid's
// exact distance is clamped to the band, as the tool's rule reads the stored field.
struct Sides {
  std::size_t tool = 0, toolWrong = 0, solid = 0, solidWrong = 0;
};
template <class ToolWins>
Sides colourSides(const Volume& v, ToolWins toolWins, Rgb8 inTool, Rgb8 inSolid, double margin = 0.5) {
  Sides s;
  const Int3 n = v.dims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        if (!(std::fabs(v.at(x, y, z)) < v.band())) continue;
        const double w = toolWins(Vec3{double(x), double(y), double(z)});
        const Rgb8 c = v.texel({x, y, z}).color();
        if (w > margin) {
          ++s.tool;
          s.toolWrong += !(c == inTool);
        } else if (w < -margin) {
          ++s.solid;
          s.solidWrong += !(c == inSolid);
        }
      }
  return s;
}

}  // namespace

TEST_CASE("a union paints what it adds in its colour, and without one adds clay", "[csg][paint]") {
  const Int3 dims{64, 64, 64};
  const Vec3 c{30, 32, 32}, t{44, 33, 31};
  const double band = Volume::kDefaultBand;
  auto solid = [&](Vec3 p) { return std::min(sdf::sphere(p, c, 15), band); };
  CsgParams p;
  p.op = CsgOp::Add;
  p.center = t;
  p.radius = 7;
  Volume painted = makeSphere(dims, c, 15), plain = painted;
  ThreadPool pool(2);
  applyCsg(painted, p, pool, kRed);
  applyCsg(plain, p, pool);
  // The tool's term wins where t < d (the rule reads d clamped to the band).
  const Sides s = colourSides(painted, [&](Vec3 x) { return solid(x) - toolDistance(p, x); }, kRed, kClayColor);
  CHECK(s.tool > 1000);
  CHECK(s.solid > 1000);
  CHECK(s.toolWrong == 0);
  CHECK(s.solidWrong == 0);
  // Colour moves no distance, and without it nothing is stored.
  std::vector<float> a(std::size_t(painted.domain().voxels())), b(a.size());
  painted.gather(painted.domain(), a.data());
  plain.gather(plain.domain(), b.data());
  CHECK(a == b);
  CHECK(plain.paintedBricks() == 0);
  CHECK(painted.paintedBricks() > 0);
  // On one thread the same.
  Volume serial = makeSphere(dims, c, 15);
  applyCsg(serial, p, ThreadPool::serial(), kRed);
  CHECK(digest(serial) == digest(painted));
}

TEST_CASE("a subtraction's walls keep the cut solid's colour, or take the tool's", "[csg][paint][extend]") {
  const Int3 dims{64, 64, 64};
  const Vec3 c{30, 32, 32}, t{44, 33, 31};
  const double band = Volume::kDefaultBand;
  auto solid = [&](Vec3 p) { return std::min(sdf::sphere(p, c, 15), band); };
  CsgParams p;
  p.op = CsgOp::Subtract;
  p.center = t;
  p.radius = 7;
  Volume red = makeSphere(dims, c, 15);
  test::paintBricks(red, [](Int3, int) { return texelOf(kRed); });
  Volume cut = red;
  applyCsg(red, p);
  applyCsg(cut, p, ThreadPool::serial(), kBlue);
  // -t > d: the tool's wall.
  const auto toolWins = [&](Vec3 x) { return -toolDistance(p, x) - solid(x); };
  const Sides kept = colourSides(red, toolWins, kRed, kRed);
  CHECK(kept.tool > 500);
  CHECK(kept.solid > 1000);
  CHECK(kept.toolWrong == 0);  // the new wall, red by extension: no clay in it
  CHECK(kept.solidWrong == 0);
  const Sides blue = colourSides(cut, toolWins, kBlue, kRed);
  CHECK(blue.tool == kept.tool);
  CHECK(blue.toolWrong == 0);
  CHECK(blue.solidWrong == 0);
}

// Before Volume::clearOutside an intersection cleared the whole volume first (Volume::fill), and
// every channel with it: the kept part came out clay.
TEST_CASE("an intersection keeps the colour of what it keeps and paints its cut in its colour", "[csg][paint]") {
  const Int3 dims{64, 64, 64};
  const Vec3 c{32, 32, 32};
  const double band = Volume::kDefaultBand;
  auto solid = [&](Vec3 p) { return std::max(std::min(sdf::sphere(p, c, 18), band), -band); };
  CsgParams p;
  p.op = CsgOp::Intersect;
  p.shape = ToolShape::Box;
  p.center = {36, 32, 32};
  p.radius = 14;
  Volume red = makeSphere(dims, c, 18);
  test::paintBricks(red, [](Int3, int) { return texelOf(kRed); });
  Volume cut = red;
  applyCsg(red, p);
  applyCsg(cut, p, ThreadPool::serial(), kBlue);
  const auto toolWins = [&](Vec3 x) { return toolDistance(p, x) - solid(x); };
  const Sides kept = colourSides(red, toolWins, kRed, kRed);
  CHECK(kept.tool > 500);
  CHECK(kept.solid > 500);
  CHECK(kept.toolWrong == 0);
  CHECK(kept.solidWrong == 0);
  const Sides blue = colourSides(cut, toolWins, kBlue, kRed);
  CHECK(blue.tool == kept.tool);
  CHECK(blue.toolWrong == 0);
  CHECK(blue.solidWrong == 0);
}

// The mask's rule (volume.hpp, diff): a voxel of weight w moves by (1 - w/255) of what it would.
// The combine does not read the mask, so the held result is the free one pulled back voxel by
// voxel, in float as diff computes it; a brick that was uniform (no channel) moves freely.
TEST_CASE("under a partial mask a CSG tool moves each voxel by (1 - w/255) of its free move", "[csg][mask]") {
  const Int3 dims{64, 64, 64};
  const Vec3 c{30, 32, 32};
  constexpr int w = 51;
  for (const CsgOp op : {CsgOp::Add, CsgOp::Subtract}) {
    CsgParams p;
    p.op = op;
    p.center = {44, 33, 31};
    p.radius = 7;
    Volume held = makeSphere(dims, c, 15);
    test::paintBricks(held, [](Int3, int) { return texelOf(kClayColor, w); });
    const Volume before = held;
    Volume free = makeSphere(dims, c, 15);
    applyCsg(held, p);
    applyCsg(free, p);
    std::size_t moved = 0, wrong = 0;
    for (int z = 0; z < dims.z; ++z)
      for (int y = 0; y < dims.y; ++y)
        for (int x = 0; x < dims.x; ++x) {
          const float old = before.at(x, y, z), now = free.at(x, y, z);
          const bool masked = before.brickPaint(Bricks::brickOf({x, y, z})) != nullptr;
          const float want = masked ? old + (1.0f - float(w) / 255.0f) * (now - old) : now;
          wrong += held.at(x, y, z) != want;
          moved += masked && now != old;
        }
    CHECK(moved > 1000);
    CHECK(wrong == 0);
  }
}
