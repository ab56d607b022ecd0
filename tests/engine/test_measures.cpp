#include <catch2/catch.hpp>

#include <numbers>

#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "support.hpp"

using namespace marzipan;

TEST_CASE("volume and area of a sphere match the analytic values", "[measures]") {
  for (double r : {8.0, 20.0, 30.0}) {
    const Volume v = makeSphere({72, 72, 72}, {35.3, 35.6, 35.1}, r);
    INFO("radius " << r);
    CHECK(insideVolume(v) == Approx(4.0 / 3.0 * std::numbers::pi * r * r * r).epsilon(0.005));
    CHECK(surfaceArea(v) == Approx(4.0 * std::numbers::pi * r * r).epsilon(0.003));
  }
}

TEST_CASE("components, bounds and gradient error", "[measures]") {
  const Vec3 a{20, 30, 30}, b{48, 30, 30};
  const Volume two = makeFromFunction({72, 60, 60}, [&](Vec3 p) {
    return std::min(sdf::sphere(p, a, 8), sdf::sphere(p, b, 8));
  }, true);
  CHECK(countComponents(two) == 2);
  const Bounds bb = boundingBox(two);
  CHECK(bb.lo.x == Approx(12).margin(0.05));
  CHECK(bb.hi.x == Approx(56).margin(0.05));
  CHECK(bb.lo.y == Approx(22).margin(0.05));
  CHECK(bb.hi.z == Approx(38).margin(0.05));
  const GradientError e = gradientError(two);
  CHECK(e.voxels > 1000);
  CHECK(e.max < 0.01);
  // A solid filling whole bricks counts them: the uniform inside is part of the component.
  const Volume big = makeSphere({96, 96, 96}, {48, 48, 48}, 40);
  CHECK(countComponents(big) == 1);
  CHECK(countComponents(Volume({32, 32, 32})) == 0);
  CHECK(boundingBox(Volume({32, 32, 32})).empty);
}

TEST_CASE("the digest tells volumes apart and ignores history", "[measures]") {
  const Volume s1 = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  const Volume s2 = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  const Volume s3 = makeSphere({64, 64, 64}, {32, 32, 32.01}, 20);
  CHECK(digest(s1) == digest(s2));
  CHECK(digest(s1) != digest(s3));
  CHECK(digestHex(s1).size() == 16);
  CHECK(digest(Volume({64, 64, 64})) != digest(Volume({64, 64, 72})));
  const Measures m = measure(s1);
  CHECK(m.components == 1);
  CHECK(m.digest == digestHex(s1));
}

TEST_CASE("the digest counts the channels once painted, and only then", "[measures][channels]") {
  Volume v = makeSphere({48, 48, 48}, {24, 24, 24}, 15);
  const std::uint64_t plain = digest(v);
  // Pinned: the digest of this sphere before volumes had channels (commit 120ebd0).
  CHECK(digestText(plain) == "83be94b2ed256fe1");
  const auto colored = test::paintBricks(v, [](Int3 b, int i) { return Texel{std::uint8_t(i), std::uint8_t(b.x), 9, 0}; });
  const std::uint64_t painted = digest(v);
  CHECK(painted != plain);
  // One texel of one brick, or only a weight, tells volumes apart.
  Volume one = v;
  test::paintBricks(one, [&](Int3 b, int i) {
    Texel t = v.brickPaint(b)->t[i];
    if (b == colored.front().brick && i == 100) t.mask = 1;
    return t;
  });
  CHECK(digest(one) != painted);
  // Painted back to the base colour: the digest of the unpainted volume again.
  v.publish(colored, false);
  CHECK(digest(v) == plain);
  // The sum of brick terms follows paint changes as a session's running digest does.
  std::uint64_t terms = digestTermSum(v);
  for (const BrickChange& c : colored) terms += brickDigestTerm(c.brick, c.after) - brickDigestTerm(c.brick, c.before);
  v.publish(colored, true);
  CHECK(digestFromTerms(v.dims(), v.band(), terms) == painted);
  // A base colour other than the clay's counts, painted or not.
  Volume blue({48, 48, 48});
  const std::uint64_t clay = digest(blue);
  blue.setBaseColor({0, 0, 255});
  CHECK(digest(blue) != clay);
}
