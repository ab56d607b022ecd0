// Strokes (server/engine/level_set/stroke.cpp): one application per message, a swept brush over
// its dabs, with a memory, and with a height; the checks of their dabs; the scratch a tool keeps.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <random>
#include <span>
#include <utility>
#include <vector>

#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/redistance.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "strokes.hpp"

using namespace marzipan;
using namespace marzipan::test_strokes;

TEST_CASE("a brush is the stroke of its dab, bit for bit, whichever path computes the window", "[level_set][stroke]") {
  // addBlob is applyStroke with one dab, which takes the brush's own window (two foot points at
  // a time); a second, weaker dab at the same centre sends the same stroke through the dab
  // search instead (the largest window of the two is the full dab's), computed by other code.
  for (const Brush tool : {Brush::AddBlob, Brush::Smooth}) {
    INFO((tool == Brush::AddBlob ? "add blob" : "smoothing"));
    Volume a = makeSolid(SolidKind::Torus, {64, 64, 64}), b = a, c = a;
    const std::uint64_t before = digest(a);
    const BrushParams p{{50, 32, 32}, 7, 0.8};
    tool == Brush::AddBlob ? addBlob(a, p) : smooth(a, p);
    CHECK(digest(a) != before);
    const StrokeDab dabs[] = {{{50, 32, 32}, 1.0}, {{50, 32, 32}, 0.5}};
    applyStroke(b, {tool, 7, 0.8}, dabs, {});
    CHECK(digest(b) == digest(a));
    // weight 0.8 at strength 1 is the same speed as strength 0.8, up to rounding
    const StrokeDab light{{50, 32, 32}, 0.8};
    applyStroke(c, {tool, 7, 1.0}, {&light, 1}, {});
    CHECK(std::fabs(insideVolume(a) - insideVolume(c)) < 1e-3);
  }
}

TEST_CASE("a straight stroke leaves a ridge of even height: no beads at dabs or message boundaries",
          "[level_set][stroke]") {
  const StrokeSettings st{Brush::AddBlob, 6, 1};
  for (const std::size_t messages : {std::size_t(1), std::size_t(4), std::size_t(31)}) {
    Volume v = strokeSlab();
    sendStroke(v, st, strokeLine(16, 62.5, 1.5), messages);  // dabs r/4 apart
    double lo = 1e9, hi = -1e9, sum = 0;
    int n = 0;
    for (double x = 26; x <= 52; x += 0.25, ++n) {  // the interior, a radius and more from the ends
      const double h = ridgeHeight(v, x);
      lo = std::min(lo, h), hi = std::max(hi, h), sum += h;
    }
    INFO(messages << " messages: ridge height " << lo << " .. " << hi);
    CHECK(sum / n > 0.8);  // one application moves the surface ~1 vu under the stroke
    CHECK((hi - lo) / (sum / n) <= 0.10);
  }
}

TEST_CASE("one smoothing application at strength 1 visibly fills a groove", "[level_set][stroke][smooth]") {
  // A groove of the remove-blob brush at radius 4 (six applications, as a sculptor's pass
  // with build-up gives), then one application of the smoothing brush at radius 7 along it.
  Volume v = strokeSlab();
  sendStroke(v, {Brush::RemoveBlob, 4, 1}, strokeLine(16, 62.5, 1), 6, true);
  const auto meanDepth = [&] {
    double sum = 0;
    int n = 0;
    for (double x = 26; x <= 52; x += 0.5, ++n) sum -= ridgeHeight(v, x);
    return sum / n;
  };
  const double groove = meanDepth();
  applyStroke(v, {Brush::Smooth, 7, 1}, strokeLine(16, 62.5, 1.75), {});
  const double smoothed = meanDepth();
  INFO("groove " << groove << " vu deep, " << smoothed << " vu after one smoothing application");
  CHECK(groove > 1);
  CHECK(smoothed < 0.65 * groove);  // one explicit step per application took off 3 %
  CHECK(smoothed > 0);  // smoothing fills in, it never raises a ridge
}

TEST_CASE("a stroke adds the same volume however its dabs are grouped or spaced", "[level_set][stroke]") {
  const StrokeSettings st{Brush::AddBlob, 6, 1};
  const double before = insideVolume(strokeSlab());
  auto added = [&](double spacing, std::size_t messages) {
    Volume v = strokeSlab();
    const auto dabs = strokeLine(16, 61, spacing);
    sendStroke(v, st, dabs, std::min(messages, dabs.size()));
    return insideVolume(v) - before;
  };
  const double one = added(1.5, 1);
  INFO("one message: " << one << " vu^3");
  CHECK(one > 200);
  for (const auto& [spacing, messages] : std::vector<std::pair<double, std::size_t>>{
           {1.5, 4}, {1.5, 32}, {0.75, 1}, {0.75, 32}, {3.0, 1}, {3.0, 16}}) {
    const double a = added(spacing, messages);
    INFO("spacing " << spacing << ", " << messages << " messages: " << a << " vu^3");
    CHECK(std::fabs(a - one) <= 0.05 * one);
  }
  // Accumulating, every message adds: 32 messages build up far more than one.
  Volume v = strokeSlab();
  sendStroke(v, st, strokeLine(16, 61, 1.5), 31, true);
  CHECK(insideVolume(v) - before > 2 * one);
}

TEST_CASE("a stroke's application leaves every voxel as it was where it adds nothing", "[level_set][stroke]") {
  const StrokeSettings st{Brush::AddBlob, 6, 1};
  const std::vector<StrokeDab> dabs = strokeLine(16, 40, 1.5);  // 17 dabs, x = 16, 17.5, ..., 40
  const std::span<const StrokeDab> all(dabs);
  Volume v = strokeSlab();
  applyStroke(v, st, all.first(9), {});
  const std::vector<StrokeDab> memory(dabs.begin(), dabs.begin() + 9);
  // Dabs the stroke applied already, sent again: nothing exceeds its memory, nothing moves.
  // (Before, the ROIs were redistanced all the same, and the kept voxels normalized again.)
  const std::uint64_t applied = digest(v);
  const Edit again = applyStroke(v, st, all.subspan(3, 4), memory);
  CHECK(again.empty());
  CHECK(digest(v) == applied);
  // The next dabs (from x = 29.5) exceed the memory only ahead of the last one it holds
  // (x = 28): the surface moves where the foot points lie past 28.75. A voxel is redistanced
  // only within the band and one voxel of those that moved: behind x = 24, every voxel keeps
  // its bits, though the new dabs' ROIs reach back to x = 23.5 and the redistance's to 20.5
  // (before, 102 voxels there changed, and 2034 in all where now 1458 do).
  const Volume kept = v;
  applyStroke(v, st, all.subspan(9), memory);
  int changedBehind = 0, changedAhead = 0;
  for (int z = 0; z < 40; ++z)
    for (int y = 0; y < 40; ++y)
      for (int x = 0; x < 80; ++x)
        if (v.at({x, y, z}) != kept.at({x, y, z})) ++(x < 24 ? changedBehind : changedAhead);
  INFO(changedAhead << " voxels changed ahead, " << changedBehind << " behind");
  CHECK(changedAhead > 500);
  CHECK(changedBehind == 0);
}

TEST_CASE("a stroke with a height moves the surface under its dab by that height", "[level_set][stroke][height]") {
  // A sphere of radius 30; one dab on its surface (off the grid's axes), radius 8.
  const Vec3 centre{48, 48, 48}, up = normalized(Vec3{0.3, 1, 0.2});
  const Vec3 top = centre + up * 30.0;
  for (const double h : {0.5, 1.0, 2.5, 4.0}) {
    for (const Brush tool : {Brush::AddBlob, Brush::RemoveBlob}) {
      Volume v = makeSphere({96, 96, 96}, centre, 30);
      const double r0 = surfaceAlong(v, centre, up, 20, 40);
      const StrokeDab dab{top, 1.0, up};
      applyStroke(v, {tool, 8, 1, h}, {&dab, 1}, {});
      const double moved = surfaceAlong(v, centre, up, 20, 40) - r0;
      const double sign = tool == Brush::AddBlob ? 1 : -1;
      INFO("height " << h << (tool == Brush::AddBlob ? " add" : " remove") << ": moved " << moved);
      CHECK(std::fabs(moved - sign * h) <= 0.03 * h + 0.05);
      // Every point of the band is still a distance to the new surface.
      const GradientError e = gradientError(v);
      INFO("gradient error max " << e.max << " mean " << e.mean);
      CHECK(e.max <= 0.1);
      CHECK(e.mean <= 0.005);
    }
  }
}

TEST_CASE("a stroke with a height builds the same however often it passes and however it is grouped",
          "[level_set][stroke][height]") {
  // Along the top of the slab, radius 8, height 4, dabs r/4 apart.
  const StrokeSettings st{Brush::AddBlob, 8, 1, 4.0};
  const double before = insideVolume(strokeSlab());
  const auto line = strokeLine(20, 60, 2);
  const auto added = [&](const std::vector<StrokeDab>& dabs, std::size_t messages, bool accumulate = false) {
    Volume v = strokeSlab();
    sendStroke(v, st, dabs, messages, accumulate);
    return std::pair{insideVolume(v) - before, ridgeHeight(v, 40)};
  };
  const auto [one, ridge] = added(line, 1);
  INFO("one pass: " << one << " vu^3, ridge " << ridge << " vu");
  CHECK(std::fabs(ridge - 4) <= 0.1);
  {
    // Where the stroke already stands at its height a message changes nothing at all: no
    // redistance creeping over its crest, pass after pass.
    Volume v = strokeSlab();
    applyStroke(v, st, line, {});
    const std::uint64_t d = digest(v);
    CHECK(applyStroke(v, st, line, line).empty());
    CHECK(digest(v) == d);
  }
  // Twelve passes back and forth over the same dabs, one message a pass or eight.
  std::vector<StrokeDab> same;
  for (int p = 0; p < 12; ++p) same.insert(same.end(), line.begin(), line.end()), std::reverse(same.end() - std::ptrdiff_t(line.size()), same.end());
  for (const std::size_t messages : {std::size_t(12), std::size_t(96)}) {
    const double a = added(same, messages).first;
    INFO("twelve passes in " << messages << " messages: " << a << " vu^3");
    CHECK(std::fabs(a - one) <= 0.01 * one);
  }
  // Twelve passes whose dabs fall elsewhere each time, as a pointer's do: they fill in the
  // shallow dips between one pass's dabs (3 % of the height halfway between dabs r/4 apart).
  std::vector<StrokeDab> scrub;
  for (int p = 0; p < 12; ++p) {
    auto dabs = strokeLine(20 + 0.17 * p, 60 - 0.13 * p, 2 - 0.05 * p);
    if (p % 2) std::reverse(dabs.begin(), dabs.end());
    scrub.insert(scrub.end(), dabs.begin(), dabs.end());
  }
  const double scrubbed = added(scrub, 96).first;
  INFO("twelve shifted passes in 96 messages: " << scrubbed << " vu^3");
  CHECK(std::fabs(scrubbed - one) <= 0.02 * one);
  // One pass in 4 or 21 messages.
  for (const std::size_t messages : {std::size_t(4), std::size_t(21)}) {
    const double a = added(line, messages).first;
    INFO(messages << " messages: " << a << " vu^3");
    CHECK(std::fabs(a - one) <= 0.05 * one);
  }
  // Without a memory every message adds its height again.
  CHECK(added(same, 12, true).first > 3 * one);
}

TEST_CASE("a stroke with a height is undone exactly by its edit's old bricks", "[level_set][stroke][height][cow]") {
  Volume v = makeSolid(SolidKind::Torus, {64, 64, 64});
  const std::uint64_t d0 = digest(v);
  const StrokeDab dabs[] = {{{50, 32, 32}, 1.0}, {{49, 36, 32}, 0.7}};
  const Edit e = applyStroke(v, {Brush::AddBlob, 8, 1, 3.5}, dabs, {});
  const std::uint64_t d1 = digest(v);
  CHECK(d1 != d0);
  v.publish(e.changes, false);
  CHECK(digest(v) == d0);
  v.publish(e.changes, true);
  CHECK(digest(v) == d1);
}

TEST_CASE("strokes refuse bad dabs and change nothing", "[level_set][stroke][errors]") {
  Volume v = strokeSlab();
  const std::uint64_t d0 = digest(v);
  const StrokeSettings st{Brush::Smooth, 6, 1};
  const StrokeDab good{{30, 16, 19.5}, 1}, far{{500, 16, 19.5}, 1}, heavy{{30, 16, 19.5}, 1.5}, none{{30, 16, 19.5}, 0};
  for (const StrokeDab& bad : {far, heavy, none}) {
    const StrokeDab dabs[] = {good, bad};
    CHECK_THROWS_AS(applyStroke(v, st, dabs, {}), EngineError);
  }
  CHECK_THROWS_AS(applyStroke(v, {Brush::Smooth, 6, 0}, {&good, 1}, {}), EngineError);
  // A height is for add and remove blob, inflate and clay only, in (0, min(radius / 2, 64)] vu.
  for (const auto& [tool, height] : std::vector<std::pair<Brush, double>>{{Brush::Smooth, 1},
                                                                         {Brush::Sharpen, 1},
                                                                         {Brush::AddBlob, 0},
                                                                         {Brush::AddBlob, -1},
                                                                         {Brush::RemoveBlob, 3.01},
                                                                         {Brush::AddBlob, std::nan("")},
                                                                         {Brush::AddBlob, INFINITY}}) {
    INFO("height " << height);
    try {
      applyStroke(v, {tool, 6, 1, height}, {&good, 1}, {});
      FAIL("accepted");
    } catch (const EngineError& e) {
      CHECK(e.field() == "height");
    }
  }
  CHECK(digest(v) == d0);
  CHECK(applyStroke(v, st, {}, {}).empty());
}

TEST_CASE("a tool over a huge region leaves no scratch of its size on the thread", "[level_set][scratch]") {
  // A dab's flags, march states and band list are kept for the next dab (thousands a minute);
  // a brush of radius 90 gathers ~188^3 voxels, whose ~3 bytes each would otherwise stay for the
  // worker thread's lifetime.
  Volume v = makeSphere({192, 192, 192}, {96, 96, 96}, 60);
  trimRedistanceScratch(0);  // whatever the tests before left on this thread (one process runs them all)
  REQUIRE(redistanceScratchBytes() == 0);
  addBlob(v, {{96, 96, 156}, 8, 1});
  const std::size_t dab = redistanceScratchBytes();
  CHECK(dab > 20000);  // at least the flags of its ~25^3 grid
  CHECK(dab < (std::size_t(1) << 22));
  addBlob(v, {{96, 96, 156}, 90, 1});
  CHECK(redistanceScratchBytes() == 0);
  addBlob(v, {{96, 96, 156}, 8, 1});  // kept again, at a dab's size
  CHECK(redistanceScratchBytes() > 20000);
  CHECK(redistanceScratchBytes() < (std::size_t(1) << 22));
}
