// Paint and mask strokes (paint.hpp) against their definition, and the mask's hold on the
// geometry tools (volume.hpp, diff): distances and colours bit for bit under a full mask.
#include <catch2/catch.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <vector>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "support.hpp"

using namespace marzipan;

namespace {

const Int3 kDims{64, 64, 64};
const Vec3 kCentre{32, 32, 32};
constexpr double kRadius = 20;

Volume sphere() { return makeSphere(kDims, kCentre, kRadius); }

// Calls fn(p, d, foot point) for every band voxel of a stored brick.
template <class F>
void forEachBandVoxel(const Volume& v, F fn) {
  v.forEachPresentBrick([&](Int3 b, const Brick& br) {
    for (int i = 0; i < kBrickVoxels; ++i) {
      const Int3 p = Bricks::origin(b) + Bricks::local(i);
      const float d = br.v[i];
      if (!(std::fabs(d) < v.band())) continue;
      const Vec3 g = v.voxelGradient(p);
      const Vec3 q = length(g) > 0 ? Vec3{double(p.x), double(p.y), double(p.z)} - g * (d / length(g))
                                   : Vec3{double(p.x), double(p.y), double(p.z)};
      fn(p, d, q);
    }
  });
}

const Rgb8 kRed{200, 20, 10};
const Vec3 kTop = kCentre + Vec3{0, kRadius, 0};

// The sphere with a stripe along x over its top, red through and through within 4 vu of its
// line (a paint stroke of radius 8, hardness 0.6, dabs 2 vu apart from x - 8 to x + 8).
Volume stripedSphere() {
  Volume v = sphere();
  PaintSettings red;
  red.color = kRed;
  red.radius = 8;
  red.hardness = 0.6;
  std::vector<StrokeDab> stripe;
  for (int k = -8; k <= 8; k += 2) stripe.push_back({kTop + Vec3{double(k), 0, 0}});
  paintStroke(v, red, stripe, {});
  return v;
}

}  // namespace

TEST_CASE("a paint dab colours the band by its foot points and moves no geometry", "[paint]") {
  Volume v = sphere();
  const auto bits = test::distanceBits(v);
  const Volume before = v;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  PaintSettings st;
  st.color = kRed;
  st.radius = 8;
  st.hardness = 0.5;
  const Edit e = paint(v, st, at);
  REQUIRE(!e.empty());
  for (const BrickChange& c : e.changes) {
    REQUIRE(c.before.data == c.after.data);  // the very brick: not a bit of distance changed
    REQUIRE(c.after.paint);
  }
  CHECK(test::differing(test::distanceBits(v), bits) == 0);
  // Inside the hard core: exactly the colour; beyond the radius: the clay; between: between.
  std::size_t core = 0, outside = 0, wrong = 0;
  forEachBandVoxel(v, [&](Int3 p, float, Vec3 q) {
    const double rho = length(q - at);
    const Texel t = v.texel(p);
    if (rho <= 3.9) {
      ++core;
      wrong += !(t == texelOf(kRed));
    } else if (rho >= 8.1) {
      ++outside;
      wrong += !(t == texelOf(kClayColor));
    } else {
      wrong += t.r < kRed.r || t.r > kClayColor.r || t.g < kRed.g || t.g > kClayColor.g || t.mask != 0;
    }
  });
  CHECK(core > 100);
  CHECK(outside > 10000);
  CHECK(wrong == 0);
  // Undo gives the volume back, digest and memory.
  v.publish(e.changes, false);
  CHECK(digest(v) == digest(before));
  CHECK(v.paintedBricks() == 0);
  CHECK(v.memoryBytes() == before.memoryBytes());
}

TEST_CASE("a paint stroke over the same spot twice is once, and without memory it accumulates", "[paint]") {
  const Vec3 at = kCentre + Vec3{0, kRadius, 0};
  PaintSettings st;
  st.color = kRed;
  st.strength = 0.5;
  st.radius = 6;
  const std::vector<StrokeDab> dabs{{at, 1}, {at + Vec3{2, 0, 0}, 0.8}, {at + Vec3{4, 0, 1}, 1}};
  Volume once = sphere();
  paintStroke(once, st, dabs, {});
  Volume twice = once;
  const Edit again = paintStroke(twice, st, dabs, dabs);
  CHECK(again.empty());
  CHECK(digest(twice) == digest(once));
  // Build-up: passing again with no memory paints on: closer to the colour.
  Volume more = once;
  paintStroke(more, st, dabs, {});
  CHECK(digest(more) != digest(once));
  const Int3 top{int(at.x), int(at.y), int(at.z)};
  CHECK(std::abs(more.texel(top).r - kRed.r) < std::abs(once.texel(top).r - kRed.r));
  // The same dabs sent in three messages, each remembering the ones before: within one level of
  // one message (each message rounds what it leaves).
  Volume pieces = sphere();
  for (std::size_t k = 0; k < dabs.size(); ++k)
    paintStroke(pieces, st, std::span<const StrokeDab>(dabs.data() + k, 1), std::span<const StrokeDab>(dabs.data(), k));
  const auto a = test::allTexels(once), b = test::allTexels(pieces);
  int worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max({worst, std::abs(a[i].r - b[i].r), std::abs(a[i].g - b[i].g), std::abs(a[i].b - b[i].b)});
  CHECK(worst <= 1);
}

TEST_CASE("mask strokes add and erase the weight, and colour paint spares masked clay", "[paint][mask]") {
  Volume v = sphere();
  const Vec3 at = kCentre + Vec3{0, 0, kRadius};
  PaintSettings mask;
  mask.mode = PaintMode::MaskAdd;
  mask.radius = 6;
  mask.hardness = 0.5;
  paint(v, mask, at);
  std::size_t frozen = 0;
  forEachBandVoxel(v, [&](Int3 p, float, Vec3 q) { frozen += length(q - at) <= 2.9 && v.texel(p).mask == 255; });
  CHECK(frozen > 50);
  const auto maskBits = test::distanceBits(v);
  PaintSettings red;
  red.color = kRed;
  red.radius = 12;
  red.hardness = 0.9;
  paint(v, red, at);
  CHECK(test::differing(test::distanceBits(v), maskBits) == 0);
  std::size_t wrong = 0, reddened = 0;
  forEachBandVoxel(v, [&](Int3 p, float, Vec3) {
    const Texel t = v.texel(p);
    if (t.mask == 255) wrong += !(t.color() == kClayColor);
    reddened += t.mask == 0 && t.color() == kRed;
  });
  CHECK(wrong == 0);
  CHECK(reddened > 100);
  // Erased with the same stroke, the weights are 0 again.
  PaintSettings erase = mask;
  erase.mode = PaintMode::MaskErase;
  erase.radius = 12;
  paint(v, erase, at);
  std::size_t weighted = 0;
  forEachBandVoxel(v, [&](Int3 p, float, Vec3) { weighted += v.texel(p).mask != 0; });
  CHECK(weighted == 0);
}

TEST_CASE("painting gives the same channels on 1 and 2 threads", "[paint][determinism]") {
  PaintSettings st;
  st.color = {10, 200, 30};
  st.radius = 30;
  st.strength = 0.7;
  st.hardness = 0.2;
  const std::vector<StrokeDab> dabs{{kCentre + Vec3{15, 10, 0}, 1}, {kCentre + Vec3{0, 12, 14}, 0.6}};
  Volume one = sphere(), two = sphere();
  ThreadPool p1(1), p2(2);
  paintStroke(one, st, dabs, {}, p1);
  paintStroke(two, st, dabs, {}, p2);
  CHECK(one.paintedBricks() > 100);
  CHECK(digest(one) == digest(two));
}

// A stroke whose region is small reads the distances once for all its bricks, a wide one brick
// by brick (paint.cpp, kGatherOnce): dabs far apart in one stroke must paint what each paints
// alone, whichever way their distances were read.
TEST_CASE("far-apart dabs of one stroke paint what each dab paints alone", "[paint]") {
  const Int3 dims{128, 128, 128};
  const Vec3 centre{64, 64, 64};
  PaintSettings st;
  st.color = {30, 60, 220};
  st.radius = 9;
  st.hardness = 0.3;
  const std::vector<StrokeDab> dabs{{centre + Vec3{-45, 0, 0}, 1}, {centre + Vec3{45, 0, 0}, 0.8},
                                    {centre + Vec3{0, 32, 32}, 0.5}};
  Volume stroke = makeSphere(dims, centre, 45), alone = makeSphere(dims, centre, 45);
  const Edit e = paintStroke(stroke, st, dabs, {});
  CHECK(e.region.voxels() > std::int64_t(64) * 64 * 64);
  for (const StrokeDab& d : dabs) {
    const Edit one = paintStroke(alone, st, {&d, 1}, {});
    CHECK(one.region.voxels() < std::int64_t(64) * 64 * 64);
  }
  CHECK(stroke.paintedBricks() > 20);
  CHECK(test::differing(test::allTexels(stroke), test::allTexels(alone)) == 0);
  CHECK(digest(stroke) == digest(alone));
}

TEST_CASE("bad paint settings and dabs are refused and change nothing", "[paint][errors]") {
  Volume v = sphere();
  const std::uint64_t d = digest(v);
  PaintSettings st;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  auto refused = [&](PaintSettings s, StrokeDab dab, const char* field) {
    try {
      paintStroke(v, s, {&dab, 1}, {});
    } catch (const EngineError& e) {
      return e.field() == std::string(field);
    }
    return false;
  };
  PaintSettings bad = st;
  bad.radius = 0.1;
  CHECK(refused(bad, {at}, "radius"));
  bad = st, bad.strength = 0;
  CHECK(refused(bad, {at}, "strength"));
  bad = st, bad.strength = std::nan("");
  CHECK(refused(bad, {at}, "strength"));
  bad = st, bad.hardness = 1;
  CHECK(refused(bad, {at}, "hardness"));
  CHECK(refused(st, {at, 0}, "weight"));
  CHECK(refused(st, {{std::nan(""), 0, 0}}, "center"));
  CHECK(refused(st, {{-500, 0, 0}}, "center"));
  CHECK(digest(v) == d);
}

// --- the mask in the geometry tools --------------------------------------------------------

TEST_CASE("under a full mask every geometry tool leaves distances and colours bit for bit", "[paint][mask]") {
  Volume v = sphere();
  PaintSettings red;
  red.color = kRed;
  red.radius = 10;
  paint(v, red, kCentre + Vec3{kRadius, 0, 0});
  PaintSettings mask;
  mask.mode = PaintMode::MaskAdd;
  mask.radius = 200;
  paint(v, mask, kCentre);
  REQUIRE(v.paintedBricks() == v.presentBricks());
  const auto bits = test::distanceBits(v);
  const auto colours = test::allTexels(v);
  const std::uint64_t frozen = digest(v);
  const Volume before = v;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  ThreadPool pool(2);
  SECTION("add blob") { CHECK(addBlob(v, {at, 8, 1}, pool).empty()); }
  SECTION("smooth") { CHECK(smooth(v, {at, 8, 1}, pool).empty()); }
  SECTION("stroke with a height") {
    const std::vector<StrokeDab> dabs{{at, 1, {1, 0, 0}}, {at + Vec3{0, 2, 0}, 1, {1, 0, 0}}};
    CHECK(applyStroke(v, {Brush::AddBlob, 8, 1, 3.0}, dabs, {}, pool).empty());
  }
  // CSG and warps write wherever their shape reaches; uniform bricks carry no mask
  // (channels.hpp), so these stay within the stored bricks: a small sphere 3 vu under the
  // surface (its distance is below the band only where the sphere's is), a short grab.
  SECTION("CSG") {
    CsgParams p;
    p.op = CsgOp::Add;
    p.center = kCentre + Vec3{kRadius - 3, 0, 0};
    p.radius = 2;
    CHECK(applyCsg(v, p, pool).empty());
    CHECK(applyCsg(v, p, pool, kRed).empty());
  }
  // A sphere 3 vu outside the surface cuts into the band only (beyond it -t < band).
  SECTION("CSG subtract") {
    CsgParams p;
    p.op = CsgOp::Subtract;
    p.center = kCentre + Vec3{kRadius + 3, 0, 0};
    p.radius = 2;
    CHECK(applyCsg(v, p, pool).empty());
    CHECK(applyCsg(v, p, pool, kRed).empty());
  }
  // A box of half side R + 2 cuts the outer band around the poles, holds every uniform brick
  // inside (t <= -5 there) and clears nothing outside its reach that was not air.
  SECTION("CSG intersect") {
    CsgParams p;
    p.op = CsgOp::Intersect;
    p.shape = ToolShape::Box;
    p.center = kCentre;
    p.radius = kRadius + 2;
    CHECK(applyCsg(v, p, pool).empty());
    CHECK(applyCsg(v, p, pool, kRed).empty());
  }
  SECTION("mean curvature flow") { CHECK(meanCurvatureFlow(v, 3, 1, pool).empty()); }
  SECTION("dilate") { CHECK(dilate(v, 1.5, pool).empty()); }
  SECTION("erode") { CHECK(erode(v, 1.5, pool).empty()); }
  SECTION("open") { CHECK(openSolid(v, 2, pool).empty()); }
  SECTION("close") { CHECK(closeSolid(v, 2, pool).empty()); }
  // Brick by brick: every slot still shares the very bricks and channels it had.
  std::size_t otherSlots = 0;
  const Int3 nb = v.brickDims();
  for (int bz = 0; bz < nb.z; ++bz)
    for (int by = 0; by < nb.y; ++by)
      for (int bx = 0; bx < nb.x; ++bx) otherSlots += !(v.brick({bx, by, bz}) == before.brick({bx, by, bz}));
  CHECK(otherSlots == 0);
  CHECK(test::differing(test::distanceBits(v), bits) == 0);
  CHECK(test::differing(test::allTexels(v), colours) == 0);
  CHECK(digest(v) == frozen);
}

// A warp is held where it writes back (Volume::diff), and along the clay's paths before its
// redistance (level_set.hpp, warps): every voxel of a masked brick keeps its bits (the whole
// field does too: tests/engine/level_set/test_warp.cpp, under a full mask).
TEST_CASE("under a full mask a grab keeps every masked voxel bit for bit", "[paint][mask]") {
  Volume v = sphere();
  PaintSettings mask;
  mask.mode = PaintMode::MaskAdd;
  mask.radius = 200;
  paint(v, mask, kCentre);
  const Volume before = v;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  grab(v, before, at, {1, 0, 0}, 4);
  std::size_t wrong = 0, held = 0;
  before.forEachPresentBrick([&](Int3 b, const Brick& br) {
    const BrickRef now = v.brick(b);
    held += now.data != nullptr;
    for (int i = 0; i < kBrickVoxels && now.data; ++i)
      wrong += std::bit_cast<std::uint32_t>(now.data->v[i]) != std::bit_cast<std::uint32_t>(br.v[i]);
    wrong += !now.data;
  });
  CHECK(held == before.presentBricks());
  CHECK(wrong == 0);
  CHECK(test::differing(test::allTexels(v), test::allTexels(before)) == 0);
}

TEST_CASE("a half-masked sphere smoothed globally keeps its masked half bit for bit", "[paint][mask]") {
  Volume v = makeSphere(kDims, kCentre, kRadius);
  // Weight 255 on every voxel of one half (every stored brick's), 0 elsewhere: x < 32, or the
  // upper half y > 32 (whose held voxels are those with y >= 33: the free ones y <= 32).
  const bool upper = GENERATE(false, true);
  const auto isHeld = [upper](Int3 p) { return upper ? p.y > 32 : p.x < 32; };
  test::paintBricks(v, [&](Int3 b, int i) { return texelOf(kClayColor, isHeld(Bricks::origin(b) + Bricks::local(i)) ? 255 : 0); });
  const Volume before = v;
  ThreadPool pool(2);
  meanCurvatureFlow(v, 20, 1, pool);
  std::size_t kept = 0, changedFree = 0, wrong = 0;
  for (int z = 0; z < kDims.z; ++z)
    for (int y = 0; y < kDims.y; ++y)
      for (int x = 0; x < kDims.x; ++x) {
        const float a = before.at(x, y, z), b = v.at(x, y, z);
        if (isHeld({x, y, z})) {
          wrong += std::bit_cast<std::uint32_t>(a) != std::bit_cast<std::uint32_t>(b);
          kept += std::fabs(a) < v.band();
        } else {
          changedFree += a != b;
        }
      }
  CHECK(wrong == 0);
  CHECK(kept > 10000);
  CHECK(changedFree > 10000);  // the free half shrank (R^2 = R0^2 - 4t: 20 steps of 1/6 is 0.34 vu)
  // And on one thread the same.
  Volume serial = before;
  meanCurvatureFlow(serial, 20, 1);
  CHECK(digest(serial) == digest(v));
}

// --- colour follows the surface (Volume::extendChannels) -------------------------------------

TEST_CASE("a blob added over a painted stripe stretches it: no clay-coloured voxel in its band", "[paint][extend]") {
  Volume v = stripedSphere();
  // A blob 4 vu high over the stripe's middle (four sub-steps, into bricks that were air).
  const StrokeDab blob(kTop, 1, {0, 1, 0});
  const Edit e = applyStroke(v, {Brush::AddBlob, 8, 1, 4.0}, {&blob, 1}, {});
  REQUIRE(!e.empty());
  // Over the whole band: every voxel whose foot point lies above the old top by 0.5 vu or more
  // (on the grown part) and within 2 vu of the stripe's plane z = 32 came from the stripe.
  std::size_t grown = 0, clay = 0;
  forEachBandVoxel(v, [&](Int3 p, float, Vec3 q) {
    if (q.y < kTop.y + 0.5 || std::fabs(q.z - kCentre.z) > 2) return;
    ++grown;
    clay += v.texel(p).color() == kClayColor;
  });
  CHECK(grown > 50);
  CHECK(clay == 0);
}

TEST_CASE("colour follows the surface alike on 1 and 2 threads, and costs nothing unpainted", "[paint][extend][determinism]") {
  Volume one = sphere(), two = sphere();
  PaintSettings red;
  red.color = kRed;
  red.radius = 10;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  paint(one, red, at);
  paint(two, red, at);
  ThreadPool p1(1), p2(2);
  dilate(one, 2, p1);
  dilate(two, 2, p2);
  CHECK(digest(one) == digest(two));
  Volume plain = sphere();
  dilate(plain, 2, p2);
  CHECK(plain.paintedBricks() == 0);
}

// The share of the band voxels whose foot point lies in the stripe's region (seen from the
// centre: within 1.5 vu of the plane z = 32 at the sphere's radius, within 5 vu of the y axis,
// on top) that read the stripe's colour.
TEST_CASE("a painted stripe stretches under dilation: every voxel of its region keeps the colour", "[paint][extend]") {
  Volume v = stripedSphere();
  const auto share = [&](const Volume& vol, std::size_t& n) {
    std::size_t inStripe = 0;
    n = 0;
    forEachBandVoxel(vol, [&](Int3 p, float, Vec3 q) {
      const Vec3 u = q - kCentre;
      const double r = length(u);
      if (u.y < 0.9 * r || std::fabs(u.z) * kRadius > 1.5 * r || std::fabs(u.x) * kRadius > 5 * r) return;
      ++n;
      inStripe += vol.texel(p).color() == kRed;
    });
    return n ? double(inStripe) / double(n) : 0.0;
  };
  std::size_t before = 0, after = 0;
  CHECK(share(v, before) == 1.0);
  ThreadPool pool(2);
  dilate(v, 4, pool);
  CHECK(share(v, after) == 1.0);
  CHECK(before > 30);
  CHECK(after > before);  // the region grew with the radius (20 -> 24 vu)
}

// --- the whole-volume mask operations ----------------------------------------------------------

TEST_CASE("mask fill, invert and clear set every stored voxel's weight and keep colours and distances", "[paint][mask]") {
  Volume v = sphere();
  const Volume plain = v;
  const std::uint64_t unpainted = digest(v);
  PaintSettings red;
  red.color = kRed;
  red.radius = 10;
  paint(v, red, kCentre + Vec3{kRadius, 0, 0});
  // A partial mask: weight 100 on x < 32 (every stored brick's voxel).
  test::paintBricks(v, [&](Int3 b, int i) {
    Texel t = v.texel(Bricks::origin(b) + Bricks::local(i));
    t.mask = Bricks::origin(b).x + Bricks::local(i).x < 32 ? 100 : 0;
    return t;
  });
  const auto bits = test::distanceBits(v);
  const auto colours = test::allTexels(v);
  const Volume painted = v;
  // Every voxel of every stored brick, against the texel it had: weight w' = rule(w), colour kept.
  const auto check = [&](auto rule) {
    std::size_t wrong = 0, seen = 0;
    painted.forEachPresentBrick([&](Int3 b, const Brick&) {
      for (int i = 0; i < kBrickVoxels; ++i) {
        const Int3 p = Bricks::origin(b) + Bricks::local(i);
        const Texel was = painted.texel(p), now = v.texel(p);
        ++seen;
        wrong += !(now.color() == was.color() && now.mask == rule(was.mask));
      }
    });
    CHECK(seen == painted.presentBricks() * std::size_t(kBrickVoxels));
    CHECK(wrong == 0);
    CHECK(test::differing(test::distanceBits(v), bits) == 0);
  };
  SECTION("fill") {
    CHECK(!maskFill(v).empty());
    check([](int) { return 255; });
    CHECK(maskFill(v).empty());
  }
  SECTION("invert, twice") {
    const Edit e = maskInvert(v);
    CHECK(e.changes.size() == painted.presentBricks());
    check([](int w) { return 255 - w; });
    maskInvert(v);
    CHECK(digest(v) == digest(painted));
    CHECK(test::differing(test::allTexels(v), colours) == 0);
  }
  SECTION("clear") {
    CHECK(!maskClear(v).empty());
    check([](int) { return 0; });
    CHECK(maskClear(v).empty());
  }
  SECTION("undo") {
    Edit e = maskFill(v);
    v.publish(e.changes, false);
    CHECK(digest(v) == digest(painted));
  }
  // On an unpainted volume: invert masks everything, invert again or clear stores nothing again.
  Volume u = plain;
  maskInvert(u);
  CHECK(u.paintedBricks() == u.presentBricks());
  maskClear(u);
  CHECK(u.paintedBricks() == 0);
  CHECK(digest(u) == unpainted);
}

// The mask's rule for every geometry tool (channels.hpp): a voxel of weight w moves by (1 - w/255)
// of what it would. With no voxel at 255 a level-set tool evolves as on free clay, and the write
// back (Volume::diff) pulls each masked voxel back, in float: the held result is the free one so
// pulled, voxel for voxel; a brick that was uniform (no channel) moves freely. Before, the speed
// was scaled by (1 - w/255) as well, and a voxel moved by about (1 - w/255)^2.
TEST_CASE("under a partial mask a level-set tool moves each voxel by (1 - w/255) of its free move", "[paint][mask]") {
  constexpr int w = 51;
  const Vec3 at = kCentre + Vec3{kRadius, 0, 0};
  const auto check = [&](auto tool) {
    Volume held = sphere();
    test::paintBricks(held, [&](Int3, int) { return texelOf(kClayColor, std::uint8_t(w)); });
    const Volume before = held;
    Volume free = sphere();
    tool(held);
    tool(free);
    std::size_t moved = 0, wrong = 0;
    for (int z = 0; z < kDims.z; ++z)
      for (int y = 0; y < kDims.y; ++y)
        for (int x = 0; x < kDims.x; ++x) {
          const float old = before.at(x, y, z), now = free.at(x, y, z);
          const bool masked = before.brickPaint(Bricks::brickOf({x, y, z})) != nullptr;
          const float want = masked ? old + (1.0f - float(w) / 255.0f) * (now - old) : now;
          wrong += std::bit_cast<std::uint32_t>(held.at(x, y, z)) != std::bit_cast<std::uint32_t>(want);
          moved += masked && now != old;
        }
    CHECK(moved > 100);
    CHECK(wrong == 0);
  };
  ThreadPool pool(2);
  SECTION("add blob") { check([&](Volume& v) { addBlob(v, {at, 8, 1}, pool); }); }
  SECTION("stroke") {
    const std::vector<StrokeDab> dabs{{at, 1, {1, 0, 0}}, {at + Vec3{0, 3, 0}, 1, {1, 0, 0}}};
    check([&](Volume& v) { applyStroke(v, {Brush::Smooth, 8, 1}, dabs, {}, pool); });
  }
  SECTION("mean curvature flow") { check([&](Volume& v) { meanCurvatureFlow(v, 1, 1, pool); }); }
  SECTION("dilate") { check([&](Volume& v) { dilate(v, 1, pool); }); }
}

// A CSG union over a painted stripe stretches it too, also a blob that overhangs the old surface
// (its centre 4 vu above the top, radius 6): on its upper sides the new normal's line passes
// over the old surface, and the way back takes the nearest old surface point instead
// (Volume::extendChannels). Before that fallback, 186 of 599 voxels of the region at h = 4 were
// clay (none at h = 0 or 2).
TEST_CASE("a CSG blob over a painted stripe stretches it, also where it overhangs", "[paint][extend][csg]") {
  Volume v = stripedSphere();
  const double h = GENERATE(0.0, 2.0, 4.0);
  CsgParams p;
  p.center = kTop + Vec3{0, h, 0};
  p.radius = 6;
  applyCsg(v, p);
  // Over the whole band: every voxel whose foot point lies above the old top by 0.5 vu or more
  // and within 2 vu of the stripe's plane z = 32 came from the stripe.
  std::size_t grown = 0, notRed = 0;
  forEachBandVoxel(v, [&](Int3 at, float, Vec3 q) {
    if (q.y < kTop.y + 0.5 || std::fabs(q.z - kCentre.z) > 2) return;
    ++grown;
    notRed += !(v.texel(at).color() == kRed);
  });
  CHECK(grown > 400);
  CHECK(notRed == 0);
}
