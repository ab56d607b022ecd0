#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <memory>
#include <cmath>
#include <cstring>
#include <vector>

#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/paint.hpp"
#include "engine/redistance.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "support.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

TEST_CASE("an empty volume is all outside and stores nothing", "[volume]") {
  Volume v({64, 64, 64});
  CHECK(v.at(10, 20, 30) == v.band());
  CHECK(v.at(-5, 0, 0) == v.band());
  CHECK(v.presentBricks() == 0);
  CHECK(v.memoryBytes() < 4096);
}

TEST_CASE("sizes outside [8, 1024] and bad bands are refused", "[volume][errors]") {
  CHECK_THROWS_AS(Volume({4, 64, 64}), EngineError);
  CHECK_THROWS_AS(Volume({64, 2048, 64}), EngineError);
  CHECK_THROWS_AS(Volume({64, 64, 64}, std::nanf("")), EngineError);
  CHECK_THROWS_AS(Volume({64, 64, 64}, 0.5f), EngineError);
  try {
    Volume({64, 64, 5000});
    FAIL("no error");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::TooLarge);
    CHECK(e.field() == "size");
  }
}

TEST_CASE("scatter and gather round-trip values and clamp to the band", "[volume]") {
  Volume v({40, 24, 16});  // sides not all multiples of 8: the last bricks are partial
  const Box b{{3, 5, 2}, {37, 24, 16}};
  std::vector<float> src(std::size_t(b.voxels()));
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = float(int(i % 13) - 6) * 0.5f;  // -3 .. 3
  src[0] = -100.0f;
  v.scatter(b, src.data(), b);
  std::vector<float> back(src.size());
  v.gather(b, back.data());
  CHECK(back[0] == -v.band());
  for (std::size_t i = 1; i < src.size(); ++i) REQUIRE(back[i] == src[i]);
  // Outside the domain reads as air, whatever was written.
  CHECK(v.at(40, 0, 0) == v.band());
}

TEST_CASE("gather reads every voxel as at() does, also boxes reaching outside the domain", "[volume]") {
  // Partial last bricks, stored and uniform ones on both sides of the surface, and boxes that
  // stick out of every face, lie wholly outside, or cut bricks on all sides.
  const Volume v = makeSphere({37, 30, 21}, {18.2, 14.7, 10.4}, 9.3);
  REQUIRE(v.presentBricks() > 0);
  for (const Box& b : {Box{{-6, -3, -9}, {45, 33, 27}}, Box{{5, 3, 1}, {31, 26, 20}}, Box{{36, -2, 4}, {39, 9, 5}},
                       Box{{-4, -4, -4}, {-1, 2, 3}}, Box{{0, 0, 0}, {37, 30, 21}}}) {
    std::vector<float> out(std::size_t(b.voxels()), std::nanf(""));
    v.gather(b, out.data());
    std::size_t i = 0, mismatches = 0;
    for (int z = b.lo.z; z < b.hi.z; ++z)
      for (int y = b.lo.y; y < b.hi.y; ++y)
        for (int x = b.lo.x; x < b.hi.x; ++x, ++i) mismatches += !(out[i] == v.at(x, y, z));
    CHECK(mismatches == 0);
  }
}

TEST_CASE("bricks that become uniform are not stored", "[volume]") {
  Volume v({32, 32, 32});
  const Box b{{0, 0, 0}, {32, 32, 32}};
  std::vector<float> inside(std::size_t(b.voxels()), -v.band());
  const auto changes = v.scatter(b, inside.data(), b);
  CHECK(changes.size() == 64);
  CHECK(v.presentBricks() == 0);
  CHECK(v.at(5, 5, 5) == -v.band());
  std::vector<float> out(std::size_t(b.voxels()), v.band());
  v.scatter(b, out.data(), b);
  CHECK(v.presentBricks() == 0);
  CHECK(digest(v) == digest(Volume({32, 32, 32})));
}

// Regions that cut a brick's rows to every width from 1 to 8 at every offset: gather, diff and
// scatter read and write such rows by overlapping pieces (volume.cpp), which must neither miss
// a voxel at either end nor touch one beside the row.
TEST_CASE("rows cut to every width and offset in a brick: a uniform brick that stays uniform is no change, one voxel off it is",
          "[volume][diff]") {
  const Int3 dims{16, 16, 16};
  const Volume air(dims);
  const float band = air.band();
  // Brick {0,0,0} stored (a ramp of values inside the band), the others uniformly outside.
  Volume stored = air;
  {
    const Box b{{0, 0, 0}, {8, 8, 8}};
    std::vector<float> ramp(std::size_t(b.voxels()));
    for (std::size_t i = 0; i < ramp.size(); ++i) ramp[i] = float(int(i % 23) - 11) * 0.25f;
    REQUIRE(stored.scatter(b, ramp.data(), b).size() == 1);
  }
  const Box all{{0, 0, 0}, dims};
  std::size_t cases = 0;
  const Volume* const bases[] = {&air, &stored};
  for (const Volume* base : bases)
    for (int lo = 0; lo < 8; ++lo)
      for (int hi = lo + 1; hi <= 8; ++hi) {
        // The region: x in [lo, hi) of bricks x = 0 and 1, every y and z of them (rows of hi - lo).
        const Box region{{lo, 0, 0}, {hi + 8, 8, 16}};
        std::vector<float> src(std::size_t(all.voxels()));
        base->gather(all, src.data());
        for (int x = lo; x < hi; ++x) {
          INFO("rows [" << lo << ", " << hi << "), voxel x " << x << (base == &air ? ", uniform" : ", stored"));
          // Beyond the band on the outside: clamps back to +band, what brick 1 holds.
          std::vector<float> same = src;
          for (int z = 0; z < 16; ++z)
            for (int y = 0; y < 8; ++y) same[std::size_t(x + 8 + 16 * (y + 16 * z))] = band * 4;
          Volume v = *base;
          CHECK(v.diff(region, same.data(), all).empty());
          CHECK(v.scatter(region, same.data(), all).empty());
          // One voxel of the uniform brick 1 (x + 8) and one of brick 0 (x) take a value inside
          // the band: both bricks change, and nothing else.
          std::vector<float> one = src;
          one[std::size_t(x + 8 + 16 * (3 + 16 * 5))] = 1.25f;
          one[std::size_t(x + 16 * (6 + 16 * 1))] = -0.5f;
          const auto changes = v.scatter(region, one.data(), all);
          REQUIRE(changes.size() == 2);
          CHECK(changes[0].brick == Int3{0, 0, 0});
          CHECK(changes[1].brick == Int3{1, 0, 0});
          CHECK(changes[1].before.uniform());
          CHECK_FALSE(changes[1].after.uniform());
          std::vector<float> back(src.size());
          v.gather(all, back.data());
          std::size_t wrong = 0;
          for (std::size_t i = 0; i < back.size(); ++i) wrong += !(back[i] == one[i]);
          CHECK(wrong == 0);
          // The voxels' own ends read back through a gather of just the cut rows.
          const Box rows{{lo, 6, 1}, {hi, 7, 2}};
          std::vector<float> row(std::size_t(rows.voxels()));
          v.gather(rows, row.data());
          for (int i = 0; i < hi - lo; ++i) CHECK(row[std::size_t(i)] == one[std::size_t(lo + i + 16 * (6 + 16 * 1))]);
          ++cases;
        }
        // The whole cut of the uniform brick 1 set to inside: it changes only when the cut is
        // the whole brick, and then to uniformly inside.
        std::vector<float> in = src;
        for (int z = 0; z < 8; ++z)
          for (int y = 0; y < 8; ++y)
            for (int x = lo; x < hi; ++x) in[std::size_t(x + 8 + 16 * (y + 16 * z))] = -band;
        Volume v = *base;
        const auto changes = v.scatter(region, in.data(), all);
        REQUIRE(changes.size() == 1);
        CHECK(changes[0].brick == Int3{1, 0, 0});
        CHECK(changes[0].after.uniform() == (lo == 0 && hi == 8));
        if (changes[0].after.uniform()) CHECK(changes[0].after.inside);
      }
  CHECK(cases == 2 * 120);
}

TEST_CASE("copies share bricks and keep their own version after an edit", "[volume][cow]") {
  Volume v = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  const Volume before = v;
  const std::uint64_t d0 = digest(before);
  const float old = v.at(52, 32, 32);
  const Box b{{40, 24, 24}, {60, 40, 40}};
  std::vector<float> src(std::size_t(b.voxels()), -1.0f);
  const auto changes = v.scatter(b, src.data(), b);
  REQUIRE_FALSE(changes.empty());
  CHECK(v.at(52, 32, 32) == -1.0f);
  CHECK(before.at(52, 32, 32) == old);
  CHECK(digest(before) == d0);
  // The old bricks returned by the edit are exactly the ones the copy still reads.
  for (const auto& c : changes) CHECK(before.brick(c.brick) == c.before);
  v.publish(changes, false);
  CHECK(digest(v) == d0);
  v.publish(changes, true);
  CHECK(v.at(52, 32, 32) == -1.0f);
}

TEST_CASE("brick drift: set, read, copied on write, cleared, and no part of the field", "[volume][drift]") {
  Volume v = makeSphere({80, 64, 64}, {40, 32, 32}, 20);
  const std::uint64_t d0 = digest(v);
  const std::size_t bytes = v.memoryBytes();
  CHECK(v.brickDrift({2, 3, 4}).none());
  CHECK(v.driftedBricks() == 0);
  // Two bricks of one tile and one of the next (tiles are 8 bricks a side); a box reaching out
  // of its brick is cut to it.
  const BrickDrift a{0.04f, {{17, 25, 33}, {20, 26, 40}}}, b{0.5f, {{64, 0, 0}, {72, 8, 8}}};
  const std::pair<Int3, BrickDrift> set[] = {{{2, 3, 4}, a}, {{3, 3, 4}, {0.02f, {{24, 24, 32}, {40, 40, 40}}}}, {{8, 0, 0}, b}};
  v.setBrickDrift(set);
  CHECK(v.brickDrift({2, 3, 4}) == a);
  CHECK(v.brickDrift({3, 3, 4}) == BrickDrift{0.02f, {{24, 24, 32}, {32, 32, 40}}});
  CHECK(v.brickDrift({8, 0, 0}) == b);
  CHECK(v.brickDrift({2, 3, 5}).none());
  CHECK(v.driftedBricks() == 3);
  std::vector<BrickDrift> row(3);
  v.brickDrifts({{1, 3, 4}, {4, 4, 5}}, row.data());
  CHECK(row[0].none());
  CHECK(row[1] == a);
  CHECK(row[2] == v.brickDrift({3, 3, 4}));
  CHECK(digest(v) == d0);
  CHECK(v.memoryBytes() > bytes);
  // A copy keeps its own drift as the original's changes.
  const Volume copy = v;
  const std::pair<Int3, BrickDrift> clear[] = {{{2, 3, 4}, {}}};
  v.setBrickDrift(clear);
  CHECK(v.brickDrift({2, 3, 4}).none());
  CHECK(v.driftedBricks() == 2);
  CHECK(copy.brickDrift({2, 3, 4}) == a);
  CHECK(copy.driftedBricks() == 3);
  // A whole-volume redistance leaves none, nor does a fill.
  Volume again = copy;
  redistanceVolume(again, ThreadPool::serial());
  CHECK(again.driftedBricks() == 0);
  CHECK(copy.driftedBricks() == 3);
  v.fill(false);
  CHECK(v.driftedBricks() == 0);
  CHECK(v.brickDrift({8, 0, 0}).none());
}

TEST_CASE("a copy shares every tile until an edit: then exactly the tiles of the changed bricks differ", "[volume][cow]") {
  const Volume base = makeSphere({128, 128, 128}, {64, 64, 64}, 40);
  const Int3 n = base.brickDims();
  constexpr int T = Volume::kTileSide;
  // The tiles (by their first brick) holding a brick of `changes`, against those sharesTile finds.
  const auto check = [&](const Volume& v, const std::vector<BrickChange>& changes) {
    int notShared = 0, changed = 0;
    for (int z = 0; z < n.z; z += T)
      for (int y = 0; y < n.y; y += T)
        for (int x = 0; x < n.x; x += T) {
          const bool holds = std::any_of(changes.begin(), changes.end(), [&](const BrickChange& c) {
            return c.brick.x / T == x / T && c.brick.y / T == y / T && c.brick.z / T == z / T;
          });
          CHECK(v.sharesTile(base, {x, y, z}) == !holds);
          CHECK(base.sharesTile(v, {x + T - 1, y, z + 1}) == !holds);
          notShared += v.sharesTile(base, {x, y, z}) ? 0 : 1;
          changed += holds ? 1 : 0;
        }
    CHECK(changed > 0);
    CHECK(notShared == changed);
  };
  Volume v = base;
  for (int z = 0; z < n.z; z += T)
    for (int y = 0; y < n.y; y += T)
      for (int x = 0; x < n.x; x += T) CHECK(v.sharesTile(base, {x, y, z}));
  SECTION("distances") {
    const Box b{{60, 60, 100}, {70, 70, 106}};
    std::vector<float> src(std::size_t(b.voxels()), -1.0f);
    check(v, v.scatter(b, src.data(), b));
  }
  SECTION("channels only") {
    PaintSettings red;
    red.color = {200, 20, 10};
    red.radius = 6;
    check(v, paint(v, red, {64, 64, 104}).changes);
  }
}

TEST_CASE("trilinear sampling reproduces a linear field and its gradient exactly", "[volume][sampling]") {
  Volume v({32, 32, 32});
  const Box b{{0, 0, 0}, {32, 32, 32}};
  std::vector<float> src(std::size_t(b.voxels()));
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) src[std::size_t(x + 32 * (y + 32 * z))] = 0.05f * x - 0.02f * y + 0.01f * z - 0.4f;
  v.scatter(b, src.data(), b);
  const Vec3 p{10.3, 7.7, 20.25};
  CHECK(v.sample(p) == Approx(0.05 * p.x - 0.02 * p.y + 0.01 * p.z - 0.4).margin(1e-6));
  const Vec3 g = v.gradient(p);
  CHECK(g.x == Approx(0.05).margin(1e-6));
  CHECK(g.y == Approx(-0.02).margin(1e-6));
  CHECK(g.z == Approx(0.01).margin(1e-6));
  const Vec3 gv = v.voxelGradient({5, 6, 7});
  CHECK(gv.x == Approx(0.05).margin(1e-6));
  CHECK(gv.y == Approx(-0.02).margin(1e-6));
}

TEST_CASE("sampling reads the same eight voxels inside a brick, across bricks and at the domain's edge",
          "[volume][sampling]") {
  // A sphere cut by the domain's faces (sides not multiples of the brick), so that corners lie
  // in stored, uniform and absent bricks and beyond the domain.
  const Volume v = makeSphere({44, 37, 29}, {20.3, 17.6, 12.2}, 15);
  auto reference = [&](Vec3 p) {
    const int i = int(std::floor(p.x)), j = int(std::floor(p.y)), k = int(std::floor(p.z));
    const double fx = p.x - i, fy = p.y - j, fz = p.z - k;
    auto c = [&](int dx, int dy, int dz) { return double(v.at(i + dx, j + dy, k + dz)); };
    const double c00 = c(0, 0, 0) + fx * (c(1, 0, 0) - c(0, 0, 0));
    const double c10 = c(0, 1, 0) + fx * (c(1, 1, 0) - c(0, 1, 0));
    const double c01 = c(0, 0, 1) + fx * (c(1, 0, 1) - c(0, 0, 1));
    const double c11 = c(0, 1, 1) + fx * (c(1, 1, 1) - c(0, 1, 1));
    const double c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
    return c0 + fz * (c1 - c0);
  };
  int checked = 0;
  for (double z = -1.5; z < 30.5; z += 0.75)
    for (double y = -1.25; y < 38.5; y += 0.5)
      for (double x = -1.75; x < 45.5; x += 0.5, ++checked) {
        const Vec3 p{x + 0.125 * std::sin(y + z), y, z};
        REQUIRE(v.sample(p) == reference(p));
      }
  CHECK(checked > 100000);
}

TEST_CASE("memory grows with surface area, not with the domain", "[volume][memory]") {
  const Volume small = makeSphere({256, 256, 256}, {128, 128, 128}, 100);
  INFO("radius 100 in 256^3: " << small.memoryBytes() << " bytes, " << small.presentBricks() << " bricks");
  CHECK(small.memoryBytes() <= std::size_t(10.55e6));  // OpenVDB's narrow band for the same sphere
  const Volume big = makeSphere({512, 512, 512}, {256, 256, 256}, 200);
  INFO("radius 200 in 512^3: " << big.memoryBytes() << " bytes");
  CHECK(big.memoryBytes() < std::size_t(50e6));
  // Area grows 4x from radius 100 to 200: memory must follow the area, not the 8x domain.
  CHECK(double(big.memoryBytes()) / double(small.memoryBytes()) < 4.5);
}

TEST_CASE("a 1024^3 domain works at its far corner and costs only its surface", "[volume][memory]") {
  const Vec3 c{990, 1000, 1010};
  Volume v = makeSphere({1024, 1024, 1024}, c, 10);
  CHECK(v.at(990, 1000, 1010) < 0);
  CHECK(v.at(0, 0, 0) == v.band());
  CHECK(v.sample({1000.0, 1000, 1010}) == Approx(0).margin(0.02));
  CHECK(insideVolume(v) == Approx(4.0 / 3.0 * 3.14159265 * 1000).epsilon(0.01));
  CHECK(v.memoryBytes() < std::size_t(2e6));  // the table of 4096 tiles plus a few bricks
  const Box corner{{1016, 1016, 1016}, {1024, 1024, 1024}};
  std::vector<float> inside(std::size_t(corner.voxels()), -1.0f);
  v.scatter(corner, inside.data(), corner);
  CHECK(v.at(1023, 1023, 1023) == -1.0f);
  CHECK(v.at(1024, 1023, 1023) == v.band());
}

TEST_CASE("scatter refuses NaN and changes nothing", "[volume][errors]") {
  Volume v = makeSphere({32, 32, 32}, {16, 16, 16}, 10);
  const std::uint64_t d0 = digest(v);
  const Box b{{20, 8, 8}, {32, 24, 24}};
  std::vector<float> src(std::size_t(b.voxels()), -1.0f);
  src.back() = std::nanf("");  // last voxel: found after the brick is already known to change
  CHECK_THROWS_AS(v.scatter(b, src.data(), b), EngineError);
  src.back() = -1.0f;
  src.front() = std::nanf("");
  CHECK_THROWS_AS(v.scatter(b, src.data(), b), EngineError);
  CHECK(digest(v) == d0);
}

// The rule scatter and diff follow, written voxel by voxel: a brick changes when some voxel of
// the region in it reads differently once clamped (==, so -0 equals +0), and then it holds the
// clamped source in the region and its old values elsewhere.
namespace {

// The bricks of `clipped` (a region inside the domain) holding a voxel whose source value
// srcAt(p), clamped to the band, differs from base's, in index order of the bricks.
template <class SrcAt>
std::vector<Int3> bricksThatDiffer(const Volume& base, const Box& clipped, SrcAt&& srcAt) {
  const float band = base.band();
  std::vector<Int3> out;
  const Box bricks = Bricks::bricksOf(clipped);
  for (int bz = bricks.lo.z; bz < bricks.hi.z; ++bz)
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const Box here = Bricks::box({bx, by, bz}).intersect(clipped);
        bool differs = false;
        for (int z = here.lo.z; z < here.hi.z; ++z)
          for (int y = here.lo.y; y < here.hi.y; ++y)
            for (int x = here.lo.x; x < here.hi.x; ++x)
              differs |= std::clamp(srcAt({x, y, z}), -band, band) != base.at(x, y, z);
        if (differs) out.push_back({bx, by, bz});
      }
  return out;
}

// The voxels of v that do not hold what the rule says after a scatter of `clipped`: the clamped
// source inside it, base's value elsewhere.
template <class SrcAt>
std::size_t voxelsAgainstRule(const Volume& v, const Volume& base, const Box& clipped, SrcAt&& srcAt) {
  const float band = base.band();
  const Int3 dims = base.dims();
  std::size_t wrong = 0;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const Int3 p{x, y, z};
        const float want = clipped.contains(p) ? std::clamp(srcAt(p), -band, band) : base.at(p);
        wrong += !(v.at(p) == want);
      }
  return wrong;
}

}  // namespace

TEST_CASE("diff lists exactly the bricks whose clamped voxels differ, read voxel by voxel", "[volume][diff]") {
  // Sides not multiples of 8, a region cut off by the domain's far faces and not aligned to
  // bricks, a source box larger than the region, stored and uniform bricks of both sides.
  const Int3 dims{45, 38, 27};
  const Volume base = makeSphere(dims, {20.3, 17.6, 12.2}, 11);
  const Box srcBox{{1, -2, 0}, {49, 38, 30}};
  const Box region{{3, 0, 1}, {48, 37, 30}};
  const Box clipped = region.intersect(base.domain());
  std::vector<float> src(std::size_t(srcBox.voxels()));
  auto srcAt = [&](Int3 p) -> float& {
    const Int3 s = srcBox.size(), l = p - srcBox.lo;
    return src[std::size_t(l.x) + std::size_t(s.x) * (std::size_t(l.y) + std::size_t(s.y) * std::size_t(l.z))];
  };
  const float band = base.band();
  for (unsigned seed = 0; seed < 6; ++seed) {
    // Start from the volume's own values (unchanged), then change a few voxels in ways that
    // do and do not count: a value beyond the band that clamps back to what is stored, -0 for
    // +0, a real change.
    for (int z = srcBox.lo.z; z < srcBox.hi.z; ++z)
      for (int y = srcBox.lo.y; y < srcBox.hi.y; ++y)
        for (int x = srcBox.lo.x; x < srcBox.hi.x; ++x) srcAt({x, y, z}) = base.at(x, y, z);
    std::uint32_t h = seed * 2654435761u + 12345u;
    auto next = [&] { return h = h * 1664525u + 1013904223u; };
    for (int i = 0; i < 40; ++i) {
      const Int3 p{clipped.lo.x + int(next() >> 8) % (clipped.hi.x - clipped.lo.x),
                   clipped.lo.y + int(next() >> 8) % (clipped.hi.y - clipped.lo.y),
                   clipped.lo.z + int(next() >> 8) % (clipped.hi.z - clipped.lo.z)};
      float& s = srcAt(p);
      switch (next() >> 30) {
        case 0: s = s >= band ? band * 4 : s <= -band ? -band * 4 : s; break;  // clamps back: no change
        case 1: s = s == 0 ? -0.0f : s; break;
        case 2: s = s + 0.25f; break;
        default: s = -s; break;
      }
    }
    // Outside the region the source may hold anything: it is never read.
    srcAt(srcBox.lo) = std::nanf("");

    Volume v = base;
    const auto listed = v.diff(region, src.data(), srcBox);
    const std::vector<Int3> expected = bricksThatDiffer(base, clipped, srcAt);
    INFO("seed " << seed);
    CHECK_FALSE(expected.empty());
    REQUIRE(listed.size() == expected.size());
    for (std::size_t i = 0; i < listed.size(); ++i) {
      CHECK(listed[i].brick == expected[i]);
      CHECK(listed[i].before == base.brick(expected[i]));
    }
    const auto changes = v.scatter(region, src.data(), srcBox);
    REQUIRE(changes.size() == listed.size());
    CHECK(voxelsAgainstRule(v, base, clipped, srcAt) == 0);
    // Bricks not listed are the very same bricks as before.
    for (int bz = 0; bz < v.brickDims().z; ++bz)
      for (int by = 0; by < v.brickDims().y; ++by)
        for (int bx = 0; bx < v.brickDims().x; ++bx) {
          const Int3 b{bx, by, bz};
          if (std::find(expected.begin(), expected.end(), b) == expected.end()) CHECK(v.brick(b) == base.brick(b));
        }
  }
}

TEST_CASE("diff refuses a NaN in a brick that otherwise would not change", "[volume][diff][errors]") {
  Volume v = makeSphere({32, 32, 32}, {16, 16, 16}, 10);
  const std::uint64_t d0 = digest(v);
  const Box b{{0, 0, 0}, {32, 32, 32}};
  std::vector<float> src(std::size_t(b.voxels()));
  v.gather(b, src.data());
  for (const std::size_t at : {std::size_t(0), src.size() / 2 + 5, src.size() - 1}) {
    std::vector<float> bad = src;
    bad[at] = std::nanf("");
    CHECK_THROWS_AS(v.diff(b, bad.data(), b), EngineError);
    CHECK_THROWS_AS(v.scatter(b, bad.data(), b), EngineError);
  }
  CHECK(v.scatter(b, src.data(), b).empty());
  CHECK(digest(v) == d0);
}

// A tool's region of 70^3 and more is compared on the pool in brick layers (volume.hpp,
// kParallelDiffVoxels): the same bricks, in the same order, as the rule says, for any thread count.
TEST_CASE("diff and scatter on 1, 2 and 3 threads give the bricks of the voxel-by-voxel rule",
          "[volume][diff][threads]") {
  // Sides not multiples of 8, a source box sticking out of the domain, a region cut by it and
  // not aligned to bricks, large enough to be split.
  const Int3 dims{90, 83, 77};
  const Volume base = makeSphere(dims, {44.3, 41.1, 37.6}, 30);
  const Box srcBox{{-3, -2, 1}, {92, 84, 80}};
  const Box region{{2, -1, 3}, {90, 83, 75}};
  const Box clipped = region.intersect(base.domain());
  REQUIRE(clipped.voxels() >= Volume::kParallelDiffVoxels);
  const float band = base.band();
  const Int3 ss = srcBox.size();
  std::vector<float> src(std::size_t(srcBox.voxels()));
  auto srcAt = [&](Int3 p) -> float& {
    const Int3 l = p - srcBox.lo;
    return src[std::size_t(l.x) + std::size_t(ss.x) * (std::size_t(l.y) + std::size_t(ss.y) * std::size_t(l.z))];
  };
  // The volume's own values, a blob pushed out on one side (whole bricks change, some become
  // uniformly inside), and values that clamp back or are -0 for +0 (no change) elsewhere.
  for (int z = srcBox.lo.z; z < srcBox.hi.z; ++z)
    for (int y = srcBox.lo.y; y < srcBox.hi.y; ++y)
      for (int x = srcBox.lo.x; x < srcBox.hi.x; ++x) {
        float& s = srcAt({x, y, z});
        s = base.at(x, y, z);
        const double bump = 14 - std::hypot(x - 70.0, y - 45.0, z - 30.0);
        if (bump > 0) s -= float(std::min(bump, 4.0));
        if ((x * 7 + y * 3 + z) % 11 == 0) s = s >= band ? band * 3 : s <= -band ? -band * 3 : s == 0 ? -0.0f : s;
      }
  const std::vector<Int3> expected = bricksThatDiffer(base, clipped, srcAt);
  REQUIRE(expected.size() > 20);
  REQUIRE(expected.front().z != expected.back().z);  // the changes span several pieces

  std::vector<BrickChange> first;
  std::uint64_t firstDigest = 0;
  for (const int threads : {1, 2, 3}) {
    INFO(threads << " threads");
    ThreadPool pool(threads);
    const auto listed = base.diff(region, src.data(), srcBox, pool);
    REQUIRE(listed.size() == expected.size());
    for (std::size_t i = 0; i < listed.size(); ++i) {
      CHECK(listed[i].brick == expected[i]);
      CHECK(listed[i].before == base.brick(expected[i]));
      if (threads == 1) continue;
      // The same new bricks as on one thread (equal values; uniform on the same side).
      const BrickRef& a = first[i].after;
      const BrickRef& b = listed[i].after;
      CHECK(a.uniform() == b.uniform());
      if (a.data && b.data) CHECK(std::memcmp(a.data->v, b.data->v, sizeof(Brick)) == 0);
      if (!a.data && !b.data) CHECK(a.inside == b.inside);
    }
    Volume v = base;
    const auto changes = v.scatter(region, src.data(), srcBox, pool);
    CHECK(changes.size() == expected.size());
    CHECK(voxelsAgainstRule(v, base, clipped, srcAt) == 0);
    if (threads == 1) {
      first = listed;
      firstDigest = digest(v);
    } else {
      CHECK(digest(v) == firstDigest);
    }
  }

  // A NaN in a brick that would not change, in the last piece: refused on any thread count,
  // and nothing is written.
  srcAt({40, 40, 73}) = std::nanf("");
  for (const int threads : {1, 2, 3}) {
    ThreadPool pool(threads);
    Volume v = base;
    CHECK_THROWS_AS(v.scatter(region, src.data(), srcBox, pool), EngineError);
    CHECK(digest(v) == digest(base));
  }
}

// --- channels (channels.hpp) -------------------------------------------------------------

using test::paintBricks;

TEST_CASE("a volume never painted stores no channels and reads its base colour", "[volume][channels]") {
  Volume v = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  CHECK(v.baseColor() == kClayColor);
  CHECK(kClayColor == Rgb8{221, 181, 155});
  CHECK(v.paintedBricks() == 0);
  CHECK(v.texel({32, 32, 12}) == Texel{221, 181, 155, 0});
  v.forEachPresentBrick([&](Int3 b, const Brick&) { REQUIRE(v.brickPaint(b) == nullptr); });
  v.setBaseColor({10, 20, 30});
  CHECK(v.texel({32, 32, 12}) == Texel{10, 20, 30, 0});
  CHECK(v.texel({-1, 0, 0}) == Texel{10, 20, 30, 0});
}

TEST_CASE("channels cost memory per painted brick, and nothing once painted back to the base", "[volume][channels][memory]") {
  Volume v = makeSphere({256, 256, 256}, {127.5, 127.5, 127.5}, 100);
  const std::size_t unpainted = v.memoryBytes();
  const std::vector<BrickChange> painted = paintBricks(v, [](Int3, int i) { return Texel{std::uint8_t(i), 0, 200, 0}; });
  CHECK(v.paintedBricks() == v.presentBricks());
  const std::size_t all = v.memoryBytes();
  INFO("unpainted " << unpainted << " bytes, painted all over " << all << " bytes, " << v.presentBricks() << " bricks");
  // One BrickPaint (2 KiB and its control block) per stored brick, plus the channels' tiles.
  CHECK(all - unpainted >= v.presentBricks() * sizeof(BrickPaint));
  CHECK(all - unpainted <= v.presentBricks() * (sizeof(BrickPaint) + 64) + 64 * 8300);
  CHECK(v.texel({127, 127, 27}).b == 200);
  // Undone, the volume is as it was, its memory too.
  v.publish(painted, false);
  CHECK(v.paintedBricks() == 0);
  CHECK(v.memoryBytes() == unpainted);
  paintBricks(v, [](Int3, int) { return Texel{1, 2, 3, 0}; });
  CHECK_THROWS_AS(v.setBaseColor({1, 1, 1}), EngineError);
}

TEST_CASE("channels of all base texels are stored as none", "[volume][channels]") {
  Volume v = makeSphere({32, 32, 32}, {16, 16, 16}, 9);
  auto plain = std::make_shared<BrickPaint>();
  std::fill(std::begin(plain->t), std::end(plain->t), texelOf(kClayColor));
  CHECK(v.canonicalPaint(plain) == nullptr);
  auto masked = std::make_shared<BrickPaint>(*plain);
  masked->t[7].mask = 1;
  const auto m = v.canonicalPaint(masked);
  REQUIRE(m != nullptr);
  CHECK(m->masked);
  auto colored = std::make_shared<BrickPaint>(*plain);
  colored->t[7].r = 0;
  const auto c = v.canonicalPaint(colored);
  REQUIRE(c != nullptr);
  CHECK_FALSE(c->masked);
}

TEST_CASE("gatherTexels reads every voxel as texel() does", "[volume][channels]") {
  Volume v = makeSphere({40, 40, 40}, {20, 20, 20}, 12);
  paintBricks(v, [](Int3 b, int i) {
    return (b.x + b.y) % 2 ? texelOf(kClayColor) : Texel{std::uint8_t(i), std::uint8_t(b.x), std::uint8_t(b.z), std::uint8_t(i / 2)};
  });
  REQUIRE(v.paintedBricks() > 0);
  const Box box{{-3, 5, 1}, {43, 22, 30}};
  std::vector<Texel> out(std::size_t(box.voxels()));
  v.gatherTexels(box, out.data());
  std::size_t k = 0, mismatches = 0;
  for (int z = box.lo.z; z < box.hi.z; ++z)
    for (int y = box.lo.y; y < box.hi.y; ++y)
      for (int x = box.lo.x; x < box.hi.x; ++x) mismatches += !(out[k++] == v.texel({x, y, z}));
  CHECK(mismatches == 0);
}

TEST_CASE("a geometry edit keeps a brick's channels, or drops them where the brick turns uniform", "[volume][channels]") {
  Volume v = makeSphere({32, 32, 32}, {16, 16, 16}, 9);
  paintBricks(v, [](Int3, int) { return Texel{1, 2, 3, 0}; });
  const std::size_t painted = v.paintedBricks();
  REQUIRE(painted == v.presentBricks());
  // Moving the whole field by 0.25 vu changes every stored brick; all stay stored.
  const Box all = v.domain();
  std::vector<float> moved(std::size_t(all.voxels()));
  v.gather(all, moved.data());
  for (float& d : moved) d += 0.25f;
  const auto changes = v.scatter(all, moved.data(), all);
  CHECK(v.paintedBricks() == v.presentBricks());
  CHECK(v.texel({16, 16, 7}) == Texel{1, 2, 3, 0});
  // Clearing the volume drops every brick's channels.
  const auto cleared = v.fill(false);
  CHECK(v.paintedBricks() == 0);
  v.publish(cleared, false);
  CHECK(v.paintedBricks() == painted);
  v.publish(changes, false);
  CHECK(v.texel({16, 16, 7}) == Texel{1, 2, 3, 0});
}

TEST_CASE("the mask holds voxels back: 255 keeps them bit for bit, 128 lets them move halfway", "[volume][channels][mask]") {
  Volume v = makeSphere({32, 32, 32}, {16, 16, 16}, 9);
  // Weight 255 at x < 16, 128 at x >= 16 (every stored brick's voxels).
  paintBricks(v, [](Int3 b, int i) { return Texel{221, 181, 155, std::uint8_t(Bricks::origin(b).x + Bricks::local(i).x < 16 ? 255 : 128)}; });
  const Volume before = v;
  const Box all = v.domain();
  std::vector<float> old(std::size_t(all.voxels())), moved;
  v.gather(all, old.data());
  moved = old;
  for (float& d : moved) d = std::clamp(d + 0.5f, -v.band(), v.band());
  v.scatter(all, moved.data(), all);
  std::size_t k = 0, wrong = 0, movedHalf = 0;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x, ++k) {
        const float now = v.at(x, y, z);
        if (!before.brick(Bricks::brickOf(Int3{x, y, z})).data) continue;  // uniform bricks carry no mask
        if (x < 16) {
          wrong += std::bit_cast<std::uint32_t>(now) != std::bit_cast<std::uint32_t>(old[k]);
        } else {
          const float expected = old[k] + (1.0f - 128.0f / 255.0f) * (moved[k] - old[k]);
          wrong += now != expected;
          movedHalf += moved[k] != old[k];
        }
      }
  CHECK(wrong == 0);
  CHECK(movedHalf > 1000);
  // Fully masked, an edit is no change at all.
  Volume frozen = before;
  paintBricks(frozen, [](Int3, int) { return Texel{221, 181, 155, 255}; });
  const Volume frozenBefore = frozen;
  CHECK(frozen.scatter(Box{{0, 0, 0}, {32, 32, 32}}.intersect(Box{{4, 4, 4}, {28, 28, 28}}), moved.data(), all).empty());
  CHECK(digest(frozen) == digest(frozenBefore));
}
