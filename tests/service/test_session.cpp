// Session (server/service/session.cpp): steps, strokes, undo/redo by digest, revisions,
// symmetry, surface picking, pressure, snapshots, loading and refused input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/progress.hpp"
#include "engine/solids.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"
#include "session_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::requireError;
using protocol::BrushTool;

namespace {

constexpr int kN = 48;
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;
const double kSurface = kC + kR;
const double kNaN = std::numeric_limits<double>::quiet_NaN();
const Vec3 kCentre{kC, kC, kC};

const Volume& sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

protocol::Op blob(BrushTool tool, Vec3 c, double radius = 6, double strength = 1) {
  return protocol::BrushOp{tool, BrushParams{c, radius, strength}};
}

Dab at(Vec3 c, std::optional<double> pressure = std::nullopt) { return Dab{c, pressure}; }
Dab ray(Vec3 o, Vec3 d, std::optional<double> pressure = std::nullopt) { return Dab{Ray{o, d}, pressure}; }

// The ray's first hit on the exact sphere |x - c| = r, or nullopt.
std::optional<Vec3> analyticHit(Vec3 c, double r, Vec3 o, Vec3 d) {
  d = normalized(d);
  const Vec3 oc = o - c;
  const double b = dot(oc, d), q = dot(oc, oc) - r * r;
  const double disc = b * b - q;
  if (disc < 0) return std::nullopt;
  const double t = -b - std::sqrt(disc);
  if (t < 0) return std::nullopt;
  return o + d * t;
}

}  // namespace

// The digest's cache of brick terms (Session::trackDigest) has kMaxCachedTerms slots: on a volume
// of more bricks, bricks (x, y, 0) and (x, y, 1) of a 128 x 128 x 2 brick domain share a slot,
// and each change of one replaces the other's entry. The digest followed through such changes,
// undone and redone, is still the one read from the whole volume.
TEST_CASE("session: the digest follows changes of bricks that share a slot of its cache", "[session]") {
  ThreadPool pool(2);
  const Vec3 c{100, 100, 7.5};
  Session s(makeSphere({1024, 1024, 16}, c, 6));
  REQUIRE(s.volume().brickDims() == Int3{128, 128, 2});
  const std::uint64_t d0 = digest(s.volume());
  REQUIRE(s.digest() == d0);
  // Dabs on the sphere's top, bottom and sides: each changes bricks of both layers.
  const std::vector<Vec3> at{{100, 100, 13.5}, {100, 100, 1.5}, {106, 100, 7.5}, {100, 94, 7.5}, {100, 100, 13.5}};
  std::vector<std::uint64_t> digests{d0};
  for (std::size_t i = 0; i < at.size(); ++i) {
    const ApplyResult r = s.apply(blob(i % 2 ? BrushTool::RemoveBlob : BrushTool::AddBlob, at[i], 3), pool);
    REQUIRE(r.changed);
    CHECK(s.digest() == digest(s.volume()));
    digests.push_back(s.digest());
  }
  CHECK(digests.back() != d0);
  for (std::size_t i = at.size(); i > 0; --i) {
    REQUIRE(s.undo().changed);
    CHECK(s.digest() == digest(s.volume()));
    CHECK(s.digest() == digests[i - 1]);
  }
  for (std::size_t i = 1; i <= at.size(); ++i) {
    REQUIRE(s.redo().changed);
    CHECK(s.digest() == digests[i]);
  }
}

TEST_CASE("session: undo and redo restore digests across ops and a 20-dab stroke", "[session]") {
  ThreadPool pool(2);
  Session s(sphere());
  std::vector<std::uint64_t> digests{digest(s.volume())};
  std::uint64_t rev = s.revision();

  const auto step = [&](const ApplyResult& r) {
    CHECK(r.changed);
    CHECK(r.revision == ++rev);
    CHECK(s.revision() == rev);
    CHECK(s.volume().revision() == rev);
    CHECK_FALSE(r.bricks.empty());
    CHECK_FALSE(r.roi.empty());
    // The digest followed brick by brick equals the one read from the whole volume.
    CHECK(s.digest() == digest(s.volume()));
  };
  step(s.apply(blob(BrushTool::AddBlob, {kSurface, kC, kC}), pool));
  digests.push_back(digest(s.volume()));
  step(s.apply(protocol::CsgToolOp{{CsgOp::Subtract, ToolShape::Sphere, {kC, kSurface, kC}, 5, 1, 0}, std::nullopt}, pool));
  digests.push_back(digest(s.volume()));
  step(s.apply(protocol::MorphOp{protocol::MorphKind::Dilate, 1}, pool));
  digests.push_back(digest(s.volume()));

  // 20 dabs in 4 messages, centres and rays mixed: one step.
  const StrokeId stroke = s.beginStroke(BrushTool::AddBlob, 4, 0.5);
  for (int call = 0; call < 4; ++call) {
    std::vector<Dab> dabs;
    for (int i = 0; i < 5; ++i) {
      const double angle = 0.12 * (5 * call + i);
      const Vec3 dir{std::cos(angle), 0.2, std::sin(angle)};
      if (i % 2 == 0) dabs.push_back(at(kCentre + normalized(dir) * (kR + 1)));
      else dabs.push_back(ray(kCentre + dir * 40, -dir, 0.8));
    }
    const ApplyResult r = s.strokeDabs(stroke, dabs, pool);
    step(r);
    REQUIRE(r.hits.size() == 5);
    CHECK(r.missed == 0);
    for (const auto& h : r.hits) CHECK(h.has_value());
  }
  s.endStroke(stroke);
  CHECK(s.history().undoSteps() == 4);
  digests.push_back(digest(s.volume()));
  step(s.apply(protocol::GlobalSmoothOp{1, 1}, pool));
  digests.push_back(digest(s.volume()));
  REQUIRE(s.history().undoSteps() == 5);

  for (std::size_t i = digests.size() - 1; i > 0; --i) {
    const HistoryResult u = s.undo();
    CHECK(u.changed);
    CHECK(u.revision == ++rev);
    CHECK(u.canRedo);
    CHECK(u.canUndo == (i > 1));
    CHECK_FALSE(u.bricks.empty());
    CHECK(digest(s.volume()) == digests[i - 1]);
    CHECK(s.digest() == digests[i - 1]);
  }
  const HistoryResult none = s.undo();
  CHECK_FALSE(none.changed);
  CHECK(none.revision == rev);
  CHECK_FALSE(none.canUndo);

  for (std::size_t i = 1; i < digests.size(); ++i) {
    const HistoryResult r = s.redo();
    CHECK(r.changed);
    CHECK(r.revision == ++rev);
    CHECK(r.canUndo);
    CHECK(digest(s.volume()) == digests[i]);
    CHECK(s.digest() == digests[i]);
  }
  CHECK_FALSE(s.redo().changed);
  CHECK(s.revision() == rev);
}

TEST_CASE("session: a new step after undos clears the redo list", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  s.apply(blob(BrushTool::AddBlob, {kSurface, kC, kC}), pool);
  s.apply(blob(BrushTool::RemoveBlob, {kC, kSurface, kC}), pool);
  s.undo();
  REQUIRE(s.canRedo());
  s.apply(blob(BrushTool::Smooth, {kC, kC, kSurface}), pool);
  CHECK_FALSE(s.canRedo());
  CHECK(s.history().undoSteps() == 2);
}

TEST_CASE("session: the history budget drops the oldest steps", "[session]") {
  ThreadPool pool(2);
  auto step = [&](Session& s, int i) { s.apply(blob(BrushTool::AddBlob, {kSurface, kC - 14 + 4 * i, kC}, 4), pool); };
  // Room for the newest of the 8 steps and about half of the older ones, counted as held: the
  // newest unpacked, older steps packed (history.hpp). What a step holds depends on how many
  // bricks the tool changes, so it is measured first.
  Session unbounded(sphere());
  step(unbounded, 0);
  const std::size_t newest = unbounded.history().bytes();
  for (int i = 1; i < 8; ++i) step(unbounded, i);
  REQUIRE(unbounded.history().droppedSteps() == 0);
  const std::size_t budget = (unbounded.history().bytes() + newest) / 2;
  Session s(sphere(), budget);
  for (int i = 0; i < 8; ++i) step(s, i);
  CHECK(s.history().bytes() <= budget);
  CHECK(s.history().undoSteps() > 0);
  CHECK(s.history().droppedSteps() > 0);
  CHECK(s.history().undoSteps() < 8);
  while (s.canUndo()) s.undo();
  CHECK(digest(s.volume()) != digest(sphere()));  // the oldest steps are gone for good
  CHECK(s.stats().historyBytes == s.history().bytes());
}

TEST_CASE("session: beginStroke refuses exactly the strokes the engine would, -32602 naming the field", "[session]") {
  // The strength and height bounds are the engine's own check (one place): whatever it refuses
  // is refused here when the stroke begins, before any dab; what it takes, a stroke may use.
  Session s(sphere());
  ThreadPool pool(1);
  const std::optional<double> heights[] = {std::nullopt, 0.0, -1.0, 0.5, 2.0, 2.0001, 4.0, 5.0, 64.0, 64.5,
                                           std::numeric_limits<double>::quiet_NaN()};
  int refused = 0, taken = 0;
  for (const BrushTool tool : {BrushTool::AddBlob, BrushTool::RemoveBlob, BrushTool::Smooth})
    for (const double radius : {4.0, 8.0, 200.0})
      for (const double strength : {0.0, 0.5, 1.0, 1.5})
        for (const std::optional<double>& height : heights) {
          std::string engineField;
          try {
            checkStrokeDab(s.volume(), StrokeSettings{engineBrush(tool), radius, strength, height},
                           StrokeDab{{kC, kC, kC}, 1, {}});
          } catch (const EngineError& e) {
            engineField = e.field();
          }
          INFO(int(tool) << " r " << radius << " strength " << strength << " height " << height.value_or(-99));
          try {
            const StrokeId id = s.beginStroke(tool, radius, strength, {}, false, {}, height);
            CHECK(engineField.empty());
            s.endStroke(id);
            ++taken;
          } catch (const ServiceError& e) {
            CHECK(e.code() == protocol::RpcCode::InvalidParams);
            CHECK(e.field() == engineField);
            ++refused;
          }
        }
  CHECK(refused > 0);
  CHECK(taken > 0);
  // What the engine does not know: an accumulating stroke has no height.
  try {
    s.beginStroke(BrushTool::AddBlob, 8, 0.5, {}, true, {}, 2.0);
    FAIL("an accumulating stroke with a height was begun");
  } catch (const ServiceError& e) {
    CHECK(e.code() == protocol::RpcCode::InvalidParams);
    CHECK(e.field() == "height");
  }
}

TEST_CASE("session: a stroke interrupted by another change continues as a new step", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  const StrokeId a = s.beginStroke(BrushTool::AddBlob, 4, 1);
  const StrokeId b = s.beginStroke(BrushTool::RemoveBlob, 4, 1);
  CHECK(a != b);
  s.strokeDabs(a, {at({kSurface, kC, kC})}, pool);
  s.strokeDabs(a, {at({kSurface, kC + 2, kC})}, pool);
  CHECK(s.history().undoSteps() == 1);
  s.strokeDabs(b, {at({kC, kSurface, kC})}, pool);
  CHECK(s.history().undoSteps() == 2);
  s.strokeDabs(a, {at({kSurface, kC + 4, kC})}, pool);
  CHECK(s.history().undoSteps() == 3);
  const std::uint64_t beforeUndo = digest(s.volume());
  s.undo();
  s.redo();
  CHECK(digest(s.volume()) == beforeUndo);
  s.strokeDabs(a, {at({kSurface, kC + 6, kC})}, pool);
  CHECK(s.history().undoSteps() == 4);
  CHECK(s.openStrokes() == 2);
  s.endStroke(a);
  s.endStroke(b);
  CHECK(s.openStrokes() == 0);
}

TEST_CASE("session: strokeSettings gives an open stroke's parameters as openStrokeList does, without its memory",
          "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  const StrokeId a = s.beginStroke(BrushTool::AddBlob, 4, 0.5, Symmetry{true, false, false}, false, {"7", "ann"}, 1.5);
  const StrokeId b = s.beginStroke(BrushTool::Smooth, 6, 0.25, {}, true);
  s.strokeDabs(a, {at({kSurface, kC, kC}), at({kSurface, kC + 2, kC})}, pool);
  for (const auto& [id, listed] : s.openStrokeList()) {
    const std::optional<Session::StrokeParams> st = s.strokeSettings(id);
    REQUIRE(st);
    CHECK(st->tool == listed.tool);
    CHECK(st->radius == listed.radius);
    CHECK(st->strength == listed.strength);
    CHECK(st->symmetry.x == listed.symmetry.x);
    CHECK(st->accumulate == listed.accumulate);
    CHECK(st->by == listed.by);
    CHECK(st->height == listed.height);
    CHECK(st->memory.empty());
    CHECK(listed.memory.size() == (id == a ? 4u : 0u));  // two dabs and their mirror images
  }
  s.endStroke(b);
  CHECK_FALSE(s.strokeSettings(b));
  CHECK_FALSE(s.strokeSettings(999));
  REQUIRE(s.strokeSettings(a));
  CHECK(s.strokeSettings(a)->height == 1.5);
}

TEST_CASE("session: when every stroke has ended only the newest step is held unpacked", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  const std::uint64_t start = digest(s.volume());
  const StrokeId a = s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, StepAuthor{"1", "A"});
  const StrokeId b = s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, StepAuthor{"2", "B"});
  s.strokeDabs(a, {at({kSurface, kC, kC})}, pool);
  s.strokeDabs(b, {at({kSurface, kC + 1, kC})}, pool);  // B's step, on A's bricks
  s.strokeDabs(a, {at({kC - kR, kC, kC})}, pool);       // far away: folds into A's step under B's
  CHECK(s.history().undoSteps() == 2);
  // On B's bricks, past what A's stroke applied (a dab it already applied would add nothing
  // and change nothing): A's stroke goes on as a new step.
  s.strokeDabs(a, {at({kSurface, kC + 1, kC})}, pool);
  CHECK(s.history().undoSteps() == 3);
  s.endStroke(a);
  s.endStroke(b);
  // A's first step grows no more and B's stroke ended: both packed.
  CHECK(s.history().unpackedSteps() == 1);
  while (s.canUndo()) s.undo();
  CHECK(digest(s.volume()) == start);
}

TEST_CASE("session: x symmetry changes the field symmetrically", "[session]") {
  ThreadPool pool(2);
  Session s(sphere());
  const Volume start = s.snapshot();
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 5, 1, Symmetry{true, false, false});
  const Vec3 p = kCentre + normalized(Vec3{1, 0.6, 0.35}) * kR;
  const ApplyResult r = s.strokeDabs(id, {at(p)}, pool);
  REQUIRE(r.changed);
  const Volume& v = s.volume();
  const Int3 mp{int(std::lround(kN - 1 - p.x)), int(std::lround(p.y)), int(std::lround(p.z))};
  CHECK(v.at(mp) < start.at(mp) - 0.3);  // the image really was sculpted
  double worst = 0;
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) worst = std::max(worst, double(std::abs(v.at(i, j, k) - v.at(kN - 1 - i, j, k))));
  CHECK(worst <= 1e-5);

  SECTION("combined mirrors give up to eight images, a dab on a plane applies once") {
    Session t(sphere());
    const StrokeId all = t.beginStroke(BrushTool::RemoveBlob, 4, 1, Symmetry{true, true, true});
    t.strokeDabs(all, {at(p)}, pool);
    const Volume& w = t.volume();
    for (int sx = 0; sx < 2; ++sx)
      for (int sy = 0; sy < 2; ++sy)
        for (int sz = 0; sz < 2; ++sz) {
          const Int3 q{int(std::lround(sx ? kN - 1 - p.x : p.x)), int(std::lround(sy ? kN - 1 - p.y : p.y)),
                       int(std::lround(sz ? kN - 1 - p.z : p.z))};
          CHECK(w.at(q) > start.at(q) + 0.3);
        }
  }
}

TEST_CASE("session: pickSurface meets an analytic sphere", "[session][pick]") {
  const Int3 dims{64, 56, 60};
  const Vec3 c{30.3, 27.7, 31.1};
  const double r = 17.4;
  const Volume v = makeSphere(dims, c, r);
  struct Case {
    Vec3 o, d;
  };
  const std::vector<Case> hits{
      {{-20, 28, 31}, {1, 0, 0}},          {{30, 80, 30}, {0, -1, 0}},     {{100, 100, 100}, c - Vec3{100, 100, 100}},
      {{30, 30, -5}, {0.1, -0.05, 1}},     {{5, 5, 5}, {1, 1, 1.2}},       {{60, 20, 40}, {-3, 0.5, -0.7}},
      {{30.3, 27.7, 60}, {0, 0, -1e-200}}, {{30, 10, 31}, {0.2, 1, 0.1}},
  };
  for (const auto& h : hits) {
    const double scale = std::max({std::abs(h.d.x), std::abs(h.d.y), std::abs(h.d.z)});
    const auto expected = analyticHit(c, r, h.o, h.d / scale);
    REQUIRE(expected);
    const auto got = pickSurface(v, h.o, h.d);
    REQUIRE(got);
    CHECK(length(*got - *expected) < 0.05);
  }
  // Misses: passing beside it, pointing away, outside the domain pointing away, parallel outside.
  CHECK_FALSE(pickSurface(v, {-20, 28 + r + 2, 31}, {1, 0, 0}));
  CHECK_FALSE(pickSurface(v, {-20, 28, 31}, {-1, 0, 0}));
  CHECK_FALSE(pickSurface(v, {500, 500, 500}, {1, 0.2, 0}));
  CHECK_FALSE(pickSurface(v, {100, 28, 31}, {0, 1, 0}));
  CHECK_FALSE(pickSurface(makeSolid(SolidKind::Empty, dims), {-20, 28, 31}, {1, 0, 0}));
  // Degenerate rays give nothing; an origin inside the solid is its own hit.
  CHECK_FALSE(pickSurface(v, {-20, 28, 31}, {0, 0, 0}));
  CHECK_FALSE(pickSurface(v, {-20, 28, 31}, {kNaN, 0, 0}));
  const auto inside = pickSurface(v, c, {1, 0, 0});
  REQUIRE(inside);
  CHECK(*inside == c);
}

TEST_CASE("session: a ray that misses gives no dab and is reported", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  const std::uint64_t d0 = digest(s.volume());
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 4, 1);
  const ApplyResult miss = s.strokeDabs(id, {ray({-10, kC + kR + 3, kC}, {1, 0, 0})}, pool);
  CHECK_FALSE(miss.changed);
  CHECK(miss.missed == 1);
  REQUIRE(miss.hits.size() == 1);
  CHECK_FALSE(miss.hits[0]);
  CHECK(miss.revision == s.revision());
  CHECK(digest(s.volume()) == d0);
  CHECK_FALSE(s.canUndo());

  const ApplyResult mixed =
      s.strokeDabs(id, {ray({-10, kC + kR + 3, kC}, {1, 0, 0}), ray({-10, kC, kC}, {1, 0, 0})}, pool);
  CHECK(mixed.changed);
  CHECK(mixed.missed == 1);
  REQUIRE(mixed.hits[1]);
  CHECK(std::abs(mixed.hits[1]->x - (kC - kR)) < 0.05);
}

TEST_CASE("session: pressure scales the displacement", "[session]") {
  ThreadPool pool(1);
  const Vec3 p{kSurface, kC, kC};
  const auto displacement = [&](double pressure) {
    Session s(sphere());
    const StrokeId id = s.beginStroke(BrushTool::AddBlob, 6, 1);
    s.strokeDabs(id, {at(p, pressure)}, pool);
    return sphere().sample(p) - s.volume().sample(p);
  };
  const double full = displacement(1), half = displacement(0.5), quarter = displacement(0.25);
  CHECK(full == Approx(1).margin(0.2));
  CHECK(half / full == Approx(0.5).margin(0.08));
  CHECK(quarter / full == Approx(0.25).margin(0.06));

  Session s(sphere());
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 6, 1);
  CHECK_FALSE(s.strokeDabs(id, {at(p, 0.0)}, pool).changed);  // pressure 0: no dab
}

TEST_CASE("session: bad input is refused with a typed error and changes nothing", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  s.apply(blob(BrushTool::AddBlob, {kSurface, kC, kC}), pool);
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 4, 1);
  s.strokeDabs(id, {at({kC, kSurface, kC})}, pool);
  const StrokeId closed = s.beginStroke(BrushTool::Smooth, 4, 1);
  s.endStroke(closed);

  const std::uint64_t d0 = digest(s.volume()), rev = s.revision();
  const std::size_t steps = s.history().steps(), bytes = s.history().bytes();
  const Dab good = at({kSurface, kC + 3, kC});
  using C = protocol::RpcCode;

  requireError([&] { s.strokeDabs(999, {good}, pool); }, C::NoSuchStroke, "stroke");
  requireError([&] { s.strokeDabs(0, {good}, pool); }, C::NoSuchStroke, "stroke");
  requireError([&] { s.strokeDabs(closed, {good}, pool); }, C::NoSuchStroke, "stroke");
  requireError([&] { s.endStroke(closed); }, C::NoSuchStroke, "stroke");
  requireError([&] { s.strokeDabs(id, {good, ray({0, 0, 0}, {0, 0, 0})}, pool); }, C::InvalidParams,
               "dabs[1].ray.direction");
  requireError([&] { s.strokeDabs(id, {good, ray({0, 0, 0}, {kNaN, 1, 0})}, pool); }, C::InvalidParams,
               "dabs[1].ray.direction");
  requireError([&] { s.strokeDabs(id, {ray({kNaN, 0, 0}, {1, 0, 0})}, pool); }, C::InvalidParams,
               "dabs[0].ray.origin");
  requireError([&] { s.strokeDabs(id, {good, at({kSurface, kC, kC}, 1.5)}, pool); }, C::InvalidParams,
               "dabs[1].pressure");
  requireError([&] { s.strokeDabs(id, {at({kSurface, kC, kC}, -0.1)}, pool); }, C::InvalidParams,
               "dabs[0].pressure");
  requireError([&] { s.strokeDabs(id, {at({kSurface, kC, kC}, kNaN)}, pool); }, C::InvalidParams,
               "dabs[0].pressure");
  requireError([&] { s.strokeDabs(id, {at({kNaN, kC, kC})}, pool); }, C::InvalidParams, "dabs[0].center");
  // Refused by the engine after two dabs were applied: rolled back.
  requireError([&] { s.strokeDabs(id, {good, good, at({5000, 0, 0})}, pool); }, C::EngineRefused,
               "dabs[2].center");
  requireError([&] { s.apply(blob(BrushTool::AddBlob, {5000, 0, 0}), pool); }, C::EngineRefused, "center");
  requireError([&] { s.apply(protocol::MorphOp{protocol::MorphKind::Erode, -1}, pool); }, C::InvalidParams,
               "radius");
  requireError([&] { s.pick(Ray{{0, 0, 0}, {0, 0, 0}}); }, C::InvalidParams, "ray.direction");
  requireError([&] { s.beginStroke(BrushTool::AddBlob, 0.1, 1); }, C::InvalidParams, "radius");
  requireError([&] { s.beginStroke(BrushTool::AddBlob, 4, 0); }, C::InvalidParams, "strength");
  requireError([&] { s.beginStroke(BrushTool::AddBlob, 4, kNaN); }, C::InvalidParams, "strength");

  CHECK(digest(s.volume()) == d0);
  CHECK(s.revision() == rev);
  CHECK(s.history().steps() == steps);
  CHECK(s.history().bytes() == bytes);
  // The stroke is still open and still folds into its step.
  CHECK(s.strokeDabs(id, {good}, pool).changed);
  CHECK(s.history().steps() == steps);
}

TEST_CASE("session: open strokes are limited", "[session]") {
  Session s(sphere());
  for (std::size_t i = 0; i < Session::kMaxOpenStrokes; ++i) s.beginStroke(BrushTool::Smooth, 4, 1);
  requireError([&] { s.beginStroke(BrushTool::Smooth, 4, 1); }, protocol::RpcCode::LimitExceeded, "stroke");
}

TEST_CASE("session: a snapshot taken before an edit still reads the old field", "[session]") {
  ThreadPool pool(2);
  Session s(sphere());
  const Volume before = s.snapshot();
  const std::uint64_t d0 = digest(before);
  const Vec3 p{kSurface, kC, kC};
  const double old = before.sample(p);
  s.apply(blob(BrushTool::AddBlob, p), pool);
  s.apply(protocol::MorphOp{protocol::MorphKind::Erode, 1}, pool);
  CHECK(before.sample(p) == old);
  CHECK(digest(before) == d0);
  CHECK(digest(s.volume()) != d0);
  s.undo();
  s.undo();
  CHECK(digest(s.volume()) == d0);
}

TEST_CASE("session: load of the same size is one undoable step, of another size a new start", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  s.apply(blob(BrushTool::AddBlob, {kSurface, kC, kC}), pool);
  const std::uint64_t sculpted = digest(s.volume());
  const std::uint64_t rev = s.revision();

  const Volume torus = makeSolid(SolidKind::Torus, {kN, kN, kN});
  const ApplyResult r = s.load(torus);
  CHECK(r.changed);
  CHECK_FALSE(r.fullRefresh);
  CHECK_FALSE(r.bricks.empty());
  CHECK(r.revision == rev + 1);
  CHECK(digest(s.volume()) == digest(torus));
  s.undo();
  CHECK(digest(s.volume()) == sculpted);
  s.redo();
  CHECK(digest(s.volume()) == digest(torus));

  Volume big = makeSolid(SolidKind::Box, {64, 56, 48});
  big.setRevision(1000);
  const ApplyResult other = s.load(big);
  CHECK(other.fullRefresh);
  CHECK(other.revision == rev + 4);
  CHECK(s.volume().dims() == Int3{64, 56, 48});
  CHECK(digest(s.volume()) == digest(big));
  CHECK_FALSE(s.canUndo());
  CHECK_FALSE(s.canRedo());
}

TEST_CASE("session: a stroke's rays pick the surface as the stroke began, or as a load left it", "[session]") {
  ThreadPool pool(1);
  Session s(sphere());
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 6, 1, {}, false, {}, 3.0);
  const Dab down = ray({kC + 0.3, 100, kC - 0.2}, {0, -1, 0});
  const ApplyResult first = s.strokeDabs(id, {down}, pool);
  REQUIRE(first.changed);
  REQUIRE(first.hits[0]);
  const auto exact = analyticHit(kCentre, kR, {kC + 0.3, 100, kC - 0.2}, {0, -1, 0});
  CHECK(first.hits[0]->y == Approx(exact->y).margin(0.05));
  // The normal it was anchored along: the sphere's there.
  CHECK(dot(first.normals[0], normalized(*exact - kCentre)) > 0.999);
  CHECK(s.volume().sample(*first.hits[0]) < -2.5);  // the stroke raised the surface above it
  // The same ray again lands where it landed, not on the stroke's own growth: nothing to add.
  const ApplyResult again = s.strokeDabs(id, {down}, pool);
  CHECK(*again.hits[0] == *first.hits[0]);
  CHECK_FALSE(again.changed);
  // A load starts the open stroke over from the loaded volume.
  const Volume torus = makeSolid(SolidKind::Torus, {kN, kN, kN});
  s.load(torus);
  const Dab ontoTorus = ray({kC + 12, 100, kC}, {0, -1, 0});
  const ApplyResult loaded = s.strokeDabs(id, {ontoTorus}, pool);
  REQUIRE(loaded.hits[0]);
  CHECK(std::fabs(torus.sample(*loaded.hits[0])) < 0.05);
}

TEST_CASE("session: stats report measures, revision and digest", "[session]") {
  ThreadPool pool(1);
  Volume start = sphere();
  start.setRevision(41);
  Session s(start);
  CHECK(s.revision() == 41);
  s.apply(blob(BrushTool::AddBlob, {kSurface, kC, kC}), pool);
  const SessionStats st = s.stats();
  CHECK(st.revision == 42);
  CHECK(st.digest == digest(s.volume()));
  CHECK(st.measures.digest == digestHex(s.volume()));
  CHECK(st.measures.components == 1);
  CHECK(st.measures.insideVolume > 4.0 / 3 * 3.14159 * kR * kR * kR * 0.95);
  CHECK(st.canUndo);
  CHECK(st.undoSteps == 1);
  CHECK(st.memoryBytes == s.volume().memoryBytes());
}

TEST_CASE("a global operation that fails or is cancelled part way changes nothing", "[session]") {
  ThreadPool pool(2);
  for (const bool cancel : {false, true}) {
    Session s(makeSolid(SolidKind::Pig, {128, 128, 128}));
    s.apply(protocol::BrushOp{BrushTool::AddBlob, BrushParams{{64, 64, 100}, 8, 1}}, pool);
    const std::uint64_t digest = s.digest(), revision = s.revision();
    const std::string hex = digestHex(s.volume());
    const std::size_t steps = s.history().undoSteps();
    // After the first of four passes: out of memory, or a cancel from another thread.
    Progress progress(
        [&](double fraction) {
          if (fraction < 0.25) return;
          if (!cancel) throw std::bad_alloc();
          progress.cancel();
        },
        std::chrono::milliseconds(0));
    progress.setTotal(4);
    const Progress::Scope scope(progress);
    if (cancel) CHECK_THROWS_AS(s.apply(protocol::GlobalSmoothOp{4, 1.0}, pool), Cancelled);
    else CHECK_THROWS_AS(s.apply(protocol::GlobalSmoothOp{4, 1.0}, pool), std::bad_alloc);
    CHECK(s.digest() == digest);
    CHECK(digestHex(s.volume()) == hex);
    CHECK(s.revision() == revision);
    CHECK(s.history().undoSteps() == steps);
    CHECK(progress.fraction() >= 0.25);
  }
}

TEST_CASE("session: open strokes' old volumes are counted, and idle or over-budget strokes are ended", "[session][strokes]") {
  // Issue 31 item 4: each open stroke keeps the volume as it began; sixteen strokes begun
  // between whole-volume morphs kept sixteen old volumes alive, uncounted, with no time limit.
  ThreadPool pool(2);
  Session s(sphere());
  std::int64_t now = 1'000'000;
  s.setStrokeClock([&] { return now; });
  const std::size_t oneVolume = s.volume().memoryBytes();
  std::vector<StrokeId> strokes;
  std::size_t heldBefore = 0;
  for (int i = 0; i < 16; ++i) {
    strokes.push_back(s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, {std::to_string(i), ""}));
    s.apply(protocol::MorphOp{i % 2 ? protocol::MorphKind::Erode : protocol::MorphKind::Dilate, 1}, pool);
    now += 1000;
  }
  heldBefore = s.strokeHeldBytes();
  INFO("one volume " << oneVolume << " bytes, held by 16 strokes " << heldBefore);
  CHECK(heldBefore > 8 * oneVolume);
  CHECK(s.endStaleStrokes(SIZE_MAX, 60'000).empty());
  CHECK(s.openStrokes() == 16);

  SECTION("over the bound, the oldest are ended until what they hold fits") {
    const std::size_t bound = 3 * oneVolume;
    const std::vector<StrokeId> ended = s.endStaleStrokes(bound, 60'000);
    CHECK(s.strokeHeldBytes() <= bound);
    REQUIRE_FALSE(ended.empty());
    CHECK(ended.front() == strokes.front());
    CHECK(std::is_sorted(ended.begin(), ended.end()));
    CHECK(s.openStrokes() == 16 - ended.size());
    CHECK(s.openStrokes() >= 1);
    requireError([&] { s.strokeDabs(ended.front(), {at({kSurface, kC, kC})}, pool); }, protocol::RpcCode::NoSuchStroke,
                 "stroke");
    // The newest stroke goes on, and a second call with nothing new is cheap and ends nothing.
    CHECK(s.strokeDabs(strokes.back(), {at({kSurface, kC, kC})}, pool).changed);
    CHECK(s.endStaleStrokes(bound, 60'000).empty());
  }
  SECTION("a stroke without a message for longer than the idle bound is ended") {
    now += 45'000;
    s.strokeDabs(strokes[5], {at({kSurface, kC, kC})}, pool);  // 5 had a message just now
    now += 20'000;
    const std::vector<StrokeId> ended = s.endStaleStrokes(SIZE_MAX, 60'000);
    CHECK(ended.size() == 15);
    CHECK(std::find(ended.begin(), ended.end(), strokes[5]) == ended.end());
    CHECK(s.openStrokes() == 1);
    CHECK(s.strokeHeldBytes() <= 2 * oneVolume);
  }
}
