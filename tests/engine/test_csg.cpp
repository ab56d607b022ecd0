#include <catch2/catch.hpp>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
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
