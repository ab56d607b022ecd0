#include <catch2/catch.hpp>

#include <cmath>

#include "engine/dense_grid.hpp"
#include "engine/redistance.hpp"
#include "engine/solids.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

namespace {

constexpr float kBand = 3.0f;

// A 72^3 grid (large enough for the pool: more voxels and band voxels than redistance.cpp and
// fast_marching.cpp march on one thread) holding a sphere of radius r around c whose values
// are not a distance: the right sign and zero set, but |grad| from 0.6 to 1.4 across the grid,
// clamped to the band as a volume's values are.
DenseGrid wrongSlopeSphere(Vec3 c, double r) {
  DenseGrid g({{0, 0, 0}, {72, 72, 72}});
  for (std::size_t i = 0; i < g.v.size(); ++i) {
    const Int3 p = g.point(i);
    const double d = length(Vec3{double(p.x), double(p.y), double(p.z)} - c) - r;
    const double slope = 1.0 + 0.4 * std::sin(0.2 * p.x) * std::cos(0.15 * p.y);
    g.v[i] = float(std::clamp(d * slope, -double(kBand), double(kBand)));
  }
  return g;
}

}  // namespace

TEST_CASE("redistancing a large region gives a distance field, the same on 1 and 2 threads", "[redistance]") {
  const Vec3 c{35.6, 36.2, 35.1};
  const double r = 24.3;
  const DenseGrid before = wrongSlopeSphere(c, r);
  const Box region = before.box.grown(-4);
  ThreadPool one(1), two(2);
  DenseGrid a = before, b = before;
  const MarchStats sa = redistanceRegion(a, region, kBand, Outside::Source, {}, one);
  const MarchStats sb = redistanceRegion(b, region, kBand, Outside::Source, {}, two);
  CHECK(sa.accepted == sb.accepted);
  CHECK(sa.accepted > 20000);  // the march is split between the two threads
  CHECK(a.v == b.v);

  // Against the exact distance: every voxel of the region within 2.5 vu of the sphere.
  double worst = 0, sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < a.v.size(); ++i) {
    const Int3 p = a.point(i);
    if (!region.contains(p)) continue;
    const double e = length(Vec3{double(p.x), double(p.y), double(p.z)} - c) - r;
    if (std::fabs(e) > 2.5) continue;
    const double err = std::fabs(a.v[i] - e);
    worst = std::max(worst, err);
    sum += err;
    ++count;
  }
  INFO("max " << worst << " mean " << sum / double(count) << " over " << count);
  // Measured 0.089 and 0.0065 (2026-11-25): the kept voxels' d / |grad| is first order where
  // the slope varies; left as they were (no normalizing) they would be off by up to 40%.
  CHECK(worst <= 0.1);
  CHECK(sum / double(count) <= 0.008);
}

TEST_CASE("only the reset boxes are redistanced, every other voxel keeps its value bit for bit", "[redistance]") {
  const DenseGrid before = wrongSlopeSphere({36.4, 35.3, 36.8}, 25.1);
  const Box region = before.box.grown(-4);
  const Box resetBoxes[] = {{{10, 8, 30}, {40, 30, 64}}, {{30, 40, 6}, {66, 64, 30}}};
  RedistanceOptions options;
  options.resetBoxes = resetBoxes;
  ThreadPool one(1), two(2);
  DenseGrid a = before, b = before;
  redistanceRegion(a, region, kBand, Outside::Source, options, one);
  redistanceRegion(b, region, kBand, Outside::Source, options, two);
  CHECK(a.v == b.v);
  std::size_t changed = 0, changedOutside = 0;
  for (std::size_t i = 0; i < a.v.size(); ++i) {
    if (a.v[i] == before.v[i]) continue;
    ++changed;
    const Int3 p = a.point(i);
    if (!resetBoxes[0].contains(p) && !resetBoxes[1].contains(p)) ++changedOutside;
  }
  CHECK(changed > 10000);
  CHECK(changedOutside == 0);
}

TEST_CASE("the band list of a gathered grid is the same whether every brick or only the stored ones are scanned",
          "[redistance]") {
  // A torus whose band crosses the domain's faces, so the grid reaches outside the domain
  // (read as +band) and the stored bricks are cut by the box on every side.
  const Volume vol = makeSolid(SolidKind::Torus, {40, 48, 36});
  REQUIRE(vol.presentBricks() > 0);
  for (const Box& b : {Box{{-5, -3, -7}, {45, 51, 41}}, Box{{3, 5, 2}, {29, 37, 30}}, Box{{10, 0, 0}, {11, 48, 36}}}) {
    const DenseGrid g = DenseGrid::gather(vol, b);
    for (const Box& scan : {b, b.grown(-2), Box{{12, 9, 4}, {27, 40, 19}}}) {
      BandVoxels all, stored;
      all.collect(g, scan, vol.band());
      stored.collect(g, scan, vol.band(), vol);
      CHECK(stored.box == all.box);
      CHECK(stored.index == all.index);
      CHECK(stored.point == all.point);
      if (scan == b) CHECK(!all.index.empty());  // the case has something to compare
    }
  }
}

TEST_CASE("a local tool's shell: far voxels are kept, lowered or reset, as exact as resetting the whole shell",
          "[redistance][roi]") {
  // A sphere of radius 20 (exact distances) with a blob of radius 5 added to it (union) or cut
  // from it (difference) inside the box `moved` only, as a local tool moves the surface inside
  // its ROI. The band around the box must become distances to the new surface: with movedBoxes,
  // far voxels of the shell keep their value (no moved cell nearer than it), keep it as an
  // upper bound the march lowers (their foot point away from the moved cells), or are reset
  // (the rest). Outside the union and inside the difference the exact distance is known:
  // min(d_sphere, d_blob) and min(|d_sphere|, d_blob).
  const Vec3 c{28.3, 27.6, 28.1}, blob = c + Vec3{0, 0, 20};
  const Box moved{{22, 21, 42}, {35, 34, 55}};
  for (const bool add : {true, false}) {
    DenseGrid before({{0, 0, 0}, {56, 56, 56}});
    auto exact = [&](Int3 p) {
      const Vec3 x{double(p.x), double(p.y), double(p.z)};
      return std::pair{length(x - c) - 20, length(x - blob) - 5};
    };
    for (std::size_t i = 0; i < before.v.size(); ++i) {
      const Int3 p = before.point(i);
      const auto [s, b] = exact(p);
      const double d = !moved.contains(p) ? s : add ? std::min(s, b) : std::max(s, -b);
      before.v[i] = float(std::clamp(d, -double(kBand), double(kBand)));
    }
    const int reach = int(std::ceil(kBand)) + 1;
    const Box resetBoxes[] = {moved.grown(reach)};
    const Box region = resetBoxes[0];
    RedistanceOptions all;
    all.resetBoxes = resetBoxes;
    all.normalizeBoxes = {&moved, 1};
    RedistanceOptions shell = all;
    shell.movedBoxes = {&moved, 1};
    ThreadPool one(1), two(2);
    DenseGrid a = before, b = before, b2 = before;
    const MarchStats sa = redistanceRegion(a, region, kBand, Outside::Source, all, one);
    const MarchStats sb = redistanceRegion(b, region, kBand, Outside::Source, shell, one);
    redistanceRegion(b2, region, kBand, Outside::Source, shell, two);
    CHECK(b.v == b2.v);

    double worstA = 0, worstB = 0, apart = 0;
    std::size_t measured = 0, kept = 0, keptChanged = 0;
    for (std::size_t i = 0; i < b.v.size(); ++i) {
      const Int3 p = b.point(i);
      apart = std::max(apart, double(std::fabs(a.v[i] - b.v[i])));
      // Far from every moved cell by more than its value: its distance cannot have changed.
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double lo = moved.lo[k] - 1, hi = moved.hi[k], x = p[k];
        const double dk = x < lo ? lo - x : (x > hi ? x - hi : 0.0);
        d2 += dk * dk;
      }
      if (region.contains(p) && !moved.contains(p) && d2 >= double(before.v[i]) * before.v[i]) {
        ++kept;
        keptChanged += b.v[i] != before.v[i];
      }
      const auto [s, bl] = exact(p);
      const double e = add ? std::min(s, bl) : std::min(-s, bl);  // outside the union, inside the difference
      if (!region.contains(p) || !(e > 0 && e < 2.5) || (add ? b.v[i] < 0 : b.v[i] > 0)) continue;
      ++measured;
      worstA = std::max(worstA, std::fabs(std::fabs(a.v[i]) - e));
      worstB = std::max(worstB, std::fabs(std::fabs(b.v[i]) - e));
    }
    INFO((add ? "add" : "cut") << ": max error resetting all " << worstA << ", with moved boxes " << worstB
                               << " over " << measured << "; apart " << apart << "; accepted " << sa.accepted
                               << " vs " << sb.accepted << "; kept " << kept);
    // Measured (2026-11-25): the same worst error both ways (0.43 add, 0.21 cut, at the crease
    // where blob and sphere meet), values at most 0.03 apart, a third fewer voxels marched.
    CHECK(measured > 1000);
    CHECK(kept > 500);
    CHECK(apart <= 0.05);
    CHECK(keptChanged == 0);
    CHECK(worstB <= worstA + 0.01);
    CHECK(sb.accepted < sa.accepted);
  }
}
