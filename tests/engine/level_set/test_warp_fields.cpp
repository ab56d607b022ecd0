// The warps' velocity fields (server/engine/level_set/warp_fields.hpp): a support's row range, and
// a capsule's inverse map of two points at once. Points in vu, volume coordinates.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <vector>

#include "engine/level_set/warp_fields.hpp"

using namespace marzipan;
using namespace marzipan::level_set::warp;

namespace {

Velocity capsule(Vec3 anchor, double radius, Vec3 seg, double plateau = 0) {
  Velocity v;
  v.kind = Velocity::Kind::Capsule;
  v.anchor = anchor;
  v.setSupport(radius, plateau);
  v.seg = seg;
  v.segLength2 = dot(seg, seg);
  v.segLength = std::sqrt(v.segLength2);
  v.segAxis = v.segLength > 0 ? seg / v.segLength : Vec3{};
  return v;
}

// The voxels of `box` where v.moves() holds and its row's range does not reach them.
int outsideTheirRow(const Velocity& v, const Box& box) {
  int missed = 0;
  for (int z = box.lo.z; z < box.hi.z; ++z)
    for (int y = box.lo.y; y < box.hi.y; ++y) {
      const auto [x0, x1] = v.row(y, z, box);
      for (int x = box.lo.x; x < box.hi.x; ++x)
        if ((x < x0 || x >= x1) && v.moves({double(x), double(y), double(z)})) ++missed;
    }
  return missed;
}

}  // namespace

TEST_CASE("a support's row range holds every voxel the field moves, tangent ones too", "[warp][fields]") {
  const Box box{{0, 0, 0}, {48, 48, 48}};
  // Found by a 2026-11-30 review among 460.8M random rows: voxel (25, 23, 26) touches the end
  // ball around anchor + seg, and without slack the row's roots rounded to none.
  const double s = std::numbers::sqrt2 - 1;
  CHECK(outsideTheirRow(capsule({27, 28, 20 + s}, 6, {-2, s, 3}), box) == 0);
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> at(14, 34), off(-6, 6), radius(2, 10);
  int missed = 0;
  for (int i = 0; i < 200; ++i) {
    // Whole and half coordinates put many voxels exactly on the support's boundary.
    const auto snap = [&](double x) { return i % 2 ? std::round(2 * x) / 2 : x; };
    const Vec3 anchor{snap(at(rng)), snap(at(rng)), snap(at(rng))};
    const Vec3 seg{snap(off(rng)), snap(off(rng)), i % 5 == 0 ? 0.0 : snap(off(rng))};
    missed += outsideTheirRow(capsule(anchor, i % 2 ? std::round(radius(rng)) : radius(rng), seg), box);
  }
  CHECK(missed == 0);
}

TEST_CASE("a capsule's inverse map of two points gives each its own bits", "[warp][fields]") {
  // Velocity::capsuleInverse2() integrates two paths at once, in the two halves of vectors
  // where both lie in end caps: each must come out as capsuleInverse() of its point alone,
  // the quartic with a plateau (a snake hook's) and the quintic (a grab's), pairs in the
  // same end cap, in different ones, between the end planes and outside the support.
  for (const double plateau : {0.5, 0.0}) {
    Velocity v = capsule({0.3, -0.2, 0.1}, 6, {2.5, 1.0, -0.7}, plateau);
    v.scale = 0.8;
    std::vector<Vec3> points;
    int caps = 0, between = 0, outside = 0;
    for (int z = -7; z <= 7; ++z)
      for (int y = -7; y <= 7; ++y)
        for (int x = -7; x <= 10; ++x) {
          const Vec3 p{double(x), double(y), double(z)};
          const Vec3 r = p - v.anchor;
          const double a = dot(r, v.segAxis);
          const Vec3 off = r - v.segAxis * a;
          if (dot(off, off) >= v.radius * v.radius) ++outside;
          else if (a >= 0 && a <= v.segLength) ++between;
          else ++caps;
          points.push_back(p);
        }
    CHECK(caps > 1000);
    CHECK(between > 100);
    CHECK(outside > 100);
    std::mt19937 rng(7);
    std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
    for (int n = 1; n <= 4; ++n) {
      int differ = 0, moved = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        // The next point (mostly the same end cap or side) and one anywhere.
        for (const std::size_t j : {(i + 1) % points.size(), pick(rng)}) {
          const Vec3 y[2] = {points[i], points[j]};
          Vec3 x[2], along[2];
          v.capsuleInverse2(y, n, x, along);
          for (int l = 0; l < 2; ++l) {
            Vec3 alongAlone;
            const Vec3 alone = v.capsuleInverse(y[l], n, alongAlone);
            // Bit for bit (a -0 against a 0 counts).
            const double pair[6] = {x[l].x, x[l].y, x[l].z, along[l].x, along[l].y, along[l].z};
            const double single[6] = {alone.x, alone.y, alone.z, alongAlone.x, alongAlone.y, alongAlone.z};
            if (std::memcmp(pair, single, sizeof pair) != 0) ++differ;
            if (!(alone == y[l])) ++moved;
          }
        }
      }
      INFO("plateau " << plateau << ", " << n << " sub-steps");
      CHECK(differ == 0);
      CHECK(moved > 1000);
    }
  }
}
