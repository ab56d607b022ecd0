#include <catch2/catch.hpp>

#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "support.hpp"

using namespace marzipan;

TEST_CASE("analytic solids hold exact distances within the band", "[solids]") {
  const Int3 dims{64, 64, 64};
  const double n = 64;
  const Vec3 c{31.5, 31.5, 31.5};
  struct Case {
    SolidKind kind;
    std::function<double(Vec3)> exact;
  };
  const Case cases[] = {
      {SolidKind::Sphere, [&](Vec3 p) { return sdf::sphere(p, c, 0.35 * n); }},
      {SolidKind::Box, [&](Vec3 p) { return sdf::box(p, c, {0.25 * n, 0.25 * n, 0.25 * n}); }},
      {SolidKind::Torus, [&](Vec3 p) { return sdf::torus(p, c, 0.28 * n, 0.1 * n, 1); }},
      {SolidKind::Cylinder, [&](Vec3 p) { return sdf::cylinder(p, c, 0.2 * n, 0.3 * n, 1); }},
  };
  for (const auto& k : cases) {
    const Volume v = makeSolid(k.kind, dims);
    INFO(solidKindName(k.kind));
    CHECK(test::maxErrorNear(v, v.domain(), v.band() - 0.01, k.exact) < 1e-5);
    CHECK(countComponents(v) == 1);
  }
}

TEST_CASE("the dumbbell and the pig are smooth distance fields of one piece", "[solids]") {
  for (SolidKind kind : {SolidKind::Dumbbell, SolidKind::Pig}) {
    const Volume v = makeSolid(kind, {96, 96, 96});
    INFO(solidKindName(kind));
    CHECK(countComponents(v) == 1);
    CHECK(test::strayBandVoxels(v) == 0);
    const GradientError e = gradientError(v);
    INFO("gradient error max " << e.max << " mean " << e.mean);
    CHECK(e.mean < 0.02);
    const Bounds b = boundingBox(v);
    REQUIRE_FALSE(b.empty);
    CHECK(b.lo.x > 0);
    CHECK(b.hi.x < 95);
  }
  // The dumbbell's handle: the middle of the domain is solid, and narrower than the spheres.
  const Volume d = makeSolid(SolidKind::Dumbbell, {96, 96, 96});
  CHECK(d.at(47, 47, 47) < 0);
  CHECK(d.at(47, 47 + 8, 47) > 0);
  CHECK(d.at(21, 47 + 12, 47) < 0);
}

TEST_CASE("solids have names and refuse bad sizes", "[solids][errors]") {
  CHECK(solidKindFromName("pig") == SolidKind::Pig);
  CHECK(solidKindFromName("empty") == SolidKind::Empty);
  CHECK_FALSE(solidKindFromName("dragon").has_value());
  CHECK(std::string(solidKindName(SolidKind::Torus)) == "torus");
  CHECK_THROWS_AS(makeSolid(SolidKind::Sphere, {2, 64, 64}), EngineError);
  CHECK_THROWS_AS(makeSphere({64, 64, 64}, {32, 32, 32}, -3), EngineError);
  CHECK_THROWS_AS(makeSphere({64, 64, 64}, {32, std::nan(""), 32}, 3), EngineError);
  CHECK(makeSolid(SolidKind::Empty, {64, 64, 64}).presentBricks() == 0);
}
