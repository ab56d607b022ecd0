// Paint and mask strokes of a Session (session.cpp beginPaint/paintDabs; PROTOCOL.md, paint and
// mask strokes) and the whole-volume mask ops (apply_op.cpp, engine maskAll), against exact
// answers: the engine's paintStroke of the same dabs bit for bit, no distance moved, the stroke
// memory, one undo step whose undo gives the starting digest and bricks back (packed under a
// newer step too: history.cpp keeps the channels), undo mine, the digest of a base colour, and a
// fully masked session that add_blob, smooth and csg_add leave bit for bit.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "engine/csg.hpp"
#include "engine/measures.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"
#include "engine/support.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"
#include "session_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::centres;
using marzipan::service::testing::requireError;

namespace {

constexpr int kN = 64;
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;
// The sphere's surface point on +x.
const Vec3 kSide{kC + kR, kC, kC};
const Rgb8 kRed{200, 20, 10};

const Volume& sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

PaintSettings red(double radius = 6) {
  PaintSettings st;
  st.color = kRed;
  st.radius = radius;
  return st;
}

PaintSettings maskBrush(double radius, PaintMode mode = PaintMode::MaskAdd) {
  PaintSettings st;
  st.mode = mode;
  st.radius = radius;
  return st;
}

}  // namespace

TEST_CASE("session paint: a stroke is the engine's paintStroke of its dabs and moves no distance", "[session][paint]") {
  Session s(sphere());
  const std::uint64_t start = s.digest();
  const std::vector<Vec3> path{kSide, kSide + Vec3{0, 3, 0}, kSide + Vec3{0, 6, 1}};
  const StrokeId id = s.beginPaint(red(), Symmetry{true, false, false});
  const ApplyResult r = s.strokeDabs(id, centres(path), ThreadPool::serial());
  CHECK(r.changed);
  CHECK(r.revision == 1);
  CHECK(r.hits.size() == 3);

  // The engine's stroke of the same dabs and their mirror images across x.
  Volume expected = sphere();
  std::vector<StrokeDab> images;
  for (const Vec3 p : path) {
    images.push_back(StrokeDab{p});
    images.push_back(StrokeDab{Vec3{(kN - 1) - p.x, p.y, p.z}});
  }
  paintStroke(expected, red(), images, {});
  CHECK(test::differing(test::allTexels(s.volume()), test::allTexels(expected)) == 0);
  CHECK(test::differing(test::distanceBits(s.volume()), test::distanceBits(sphere())) == 0);
  // The mirror image on -x is painted as the dab on +x.
  CHECK(s.volume().texel({int(std::lround(kC + kR)), int(kC), int(kC)}) == texelOf(kRed));
  CHECK(s.volume().texel({int(std::lround(kC - kR)), int(kC), int(kC)}) == texelOf(kRed));
  // The session's running digest is the volume's, and it counts the colour.
  CHECK(s.digest() == digest(s.volume()));
  CHECK(s.digest() != start);

  // The same dabs again: the stroke's memory holds them, nothing changes.
  const ApplyResult again = s.strokeDabs(id, centres(path), ThreadPool::serial());
  CHECK_FALSE(again.changed);
  CHECK(again.revision == 1);
  s.endStroke(id);
  const std::vector<StepInfo> steps = s.steps();
  REQUIRE(steps.size() == 1);
  CHECK(steps[0].tool == "paint");
}

TEST_CASE("session paint: accumulate adds again, pressure scales, a mask stroke is named mask", "[session][paint]") {
  Session s(sphere());
  PaintSettings light = red();
  light.strength = 0.5;
  const StrokeId id = s.beginPaint(light, {}, true);
  const Int3 at{int(std::lround(kC + kR)), int(kC), int(kC)};
  s.strokeDabs(id, centres({kSide}), ThreadPool::serial());
  const Texel once = s.volume().texel(at);
  CHECK(s.strokeDabs(id, centres({kSide}), ThreadPool::serial()).changed);
  const Texel twice = s.volume().texel(at);
  // Halfway each time: 221 -> 211 (210.5 rounded up) -> 206 (205.5 up) in red.
  CHECK(int(once.r) == 211);
  CHECK(int(twice.r) == 206);
  s.endStroke(id);

  // Pressure 0.5 of strength 1 is the same alpha as strength 0.5 at pressure 1.
  Session p(sphere());
  const StrokeId pid = p.beginPaint(red());
  p.strokeDabs(pid, {Dab{kSide, 0.5}}, ThreadPool::serial());
  CHECK(p.volume().texel(at) == once);

  const StrokeId mid = p.beginPaint(maskBrush(4));
  p.strokeDabs(mid, centres({kSide}), ThreadPool::serial());
  p.endStroke(mid);
  CHECK(p.volume().texel(at).mask == 255);
  const std::vector<StepInfo> steps = p.steps();
  REQUIRE(steps.size() == 2);
  CHECK(steps[1].tool == "mask");
}

TEST_CASE("session paint: one undo step gives the start back bit for bit, also packed under a newer step",
          "[session][paint][history]") {
  Session s(sphere());
  const std::uint64_t start = s.digest();
  const StrokeId id = s.beginPaint(red());
  s.strokeDabs(id, centres({kSide}), ThreadPool::serial());
  s.strokeDabs(id, centres({kSide + Vec3{0, 4, 0}}), ThreadPool::serial());
  s.endStroke(id);
  const std::uint64_t painted = s.digest();
  const auto paintedTexels = test::allTexels(s.volume());
  REQUIRE(s.steps().size() == 1);

  SECTION("the newest step") {
    CHECK(s.undo().changed);
    CHECK(s.digest() == start);
    CHECK(digest(s.volume()) == start);
    CHECK(s.volume().paintedBricks() == 0);
    CHECK(s.redo().changed);
    CHECK(s.digest() == painted);
    CHECK(test::differing(test::allTexels(s.volume()), paintedTexels) == 0);
  }
  SECTION("packed under a newer step, then moved between the lists (packed again each time)") {
    // A mask stroke elsewhere packs the paint step (history.cpp); undoing both must give the
    // channels back exactly, which packing that ignored BrickRef::paint did not.
    const StrokeId m = s.beginPaint(maskBrush(4));
    s.strokeDabs(m, centres({Vec3{kC - kR, kC, kC}}), ThreadPool::serial());
    s.endStroke(m);
    const std::uint64_t masked = s.digest();
    CHECK(s.undo().changed);
    CHECK(s.digest() == painted);
    CHECK(test::differing(test::allTexels(s.volume()), paintedTexels) == 0);
    CHECK(s.undo().changed);
    CHECK(s.digest() == start);
    CHECK(s.volume().paintedBricks() == 0);
    CHECK(s.redo().changed);
    CHECK(s.digest() == painted);
    CHECK(test::differing(test::allTexels(s.volume()), paintedTexels) == 0);
    CHECK(s.redo().changed);
    CHECK(s.digest() == masked);
    CHECK(digest(s.volume()) == masked);
  }
}

TEST_CASE("session paint: undo mine takes one author's paint away and leaves the other's", "[session][paint][history]") {
  Session s(sphere());
  const StepAuthor ada{"1", "Ada"}, bo{"2", "Bo"};
  const StrokeId a = s.beginPaint(red(), {}, false, ada);
  s.strokeDabs(a, centres({kSide}), ThreadPool::serial());
  s.endStroke(a);
  const std::uint64_t adaOnly = s.digest();
  PaintSettings blue = red();
  blue.color = {10, 20, 200};
  const StrokeId b = s.beginPaint(blue, {}, false, bo);
  s.strokeDabs(b, centres({Vec3{kC - kR, kC, kC}}), ThreadPool::serial());
  s.endStroke(b);
  const std::uint64_t both = s.digest();
  const HistoryResult undone = s.undoMine("2");
  CHECK(undone.changed);
  CHECK(s.digest() == adaOnly);
  CHECK(s.redoMine("2").changed);
  CHECK(s.digest() == both);
  // Ada's paint is under Bo's in the list but elsewhere: it goes alone.
  CHECK(s.undoMine("1").changed);
  Session bob(sphere());
  const StrokeId only = bob.beginPaint(blue);
  bob.strokeDabs(only, centres({Vec3{kC - kR, kC, kC}}), ThreadPool::serial());
  CHECK(s.digest() == bob.digest());
}

TEST_CASE("session paint: the whole mask ops are one step each, named as their methods", "[session][paint][mask]") {
  Session s(sphere());
  const std::uint64_t start = s.digest();
  CHECK(s.apply(protocol::MaskOp{MaskAction::Fill}, ThreadPool::serial()).changed);
  const std::uint64_t full = s.digest();
  CHECK(full != start);
  CHECK(s.apply(protocol::MaskOp{MaskAction::Invert}, ThreadPool::serial()).changed);
  // Full inverted is empty: the start again, channels and all.
  CHECK(s.digest() == start);
  CHECK(s.volume().paintedBricks() == 0);
  CHECK(s.apply(protocol::MaskOp{MaskAction::Fill}, ThreadPool::serial()).changed);
  CHECK(s.apply(protocol::MaskOp{MaskAction::Clear}, ThreadPool::serial()).changed);
  // Clearing an empty mask changes nothing and makes no step.
  CHECK_FALSE(s.apply(protocol::MaskOp{MaskAction::Clear}, ThreadPool::serial()).changed);
  std::vector<std::string> names;
  for (const StepInfo& st : s.steps()) names.push_back(st.tool);
  CHECK(names == std::vector<std::string>{"mask.fill", "mask.invert", "mask.fill", "mask.clear"});
  CHECK(s.undo().changed);
  CHECK(s.digest() == full);
}

TEST_CASE("session paint: under a full mask add_blob, smooth and csg_add leave distances and colours bit for bit",
          "[session][paint][mask]") {
  Session s(sphere());
  const StrokeId p = s.beginPaint(red(8));
  s.strokeDabs(p, centres({kSide}), ThreadPool::serial());
  s.endStroke(p);
  s.apply(protocol::MaskOp{MaskAction::Fill}, ThreadPool::serial());
  const auto bits = test::distanceBits(s.volume());
  const auto colours = test::allTexels(s.volume());
  const std::uint64_t frozen = s.digest();
  const std::uint64_t revision = s.revision();
  ThreadPool pool(2);
  SECTION("an add_blob stroke") {
    const StrokeId id = s.beginStroke(protocol::BrushTool::AddBlob, 8, 1);
    const ApplyResult r = s.strokeDabs(id, centres({kSide, kSide + Vec3{0, 3, 0}}), ThreadPool::serial());
    CHECK_FALSE(r.changed);
  }
  SECTION("a smooth stroke") {
    const StrokeId id = s.beginStroke(protocol::BrushTool::Smooth, 8, 1);
    CHECK_FALSE(s.strokeDabs(id, centres({kSide}), ThreadPool::serial()).changed);
  }
  SECTION("csg_add") {
    // A small sphere just under the surface: within the stored bricks, where the mask lives
    // (channels.hpp: uniform bricks carry none).
    protocol::CsgToolOp op;
    op.params.op = CsgOp::Add;
    op.params.center = kSide - Vec3{3, 0, 0};
    op.params.radius = 2;
    CHECK_FALSE(s.apply(op, pool).changed);
  }
  CHECK(s.revision() == revision);
  CHECK(test::differing(test::distanceBits(s.volume()), bits) == 0);
  CHECK(test::differing(test::allTexels(s.volume()), colours) == 0);
  CHECK(s.digest() == frozen);
}

TEST_CASE("session paint: a base colour counts in the digest, an unpainted clay session's digest is its distances'",
          "[session][paint]") {
  Session clay(sphere());
  CHECK(clay.digest() == digest(sphere()));
  Volume blue = sphere();
  blue.setBaseColor({120, 130, 150});
  Session s(blue);
  CHECK(s.digest() == digest(blue));
  CHECK(s.digest() != clay.digest());
  // A fork keeps the base colour and the paint.
  const StrokeId id = s.beginPaint(red());
  s.strokeDabs(id, centres({kSide}), ThreadPool::serial());
  const Volume forked = s.forkVolume();
  CHECK(forked.baseColor() == Rgb8{120, 130, 150});
  CHECK(digest(forked) == s.digest());
  // Loading a volume of another base colour replaces the field (history cleared): no step of
  // bricks could say what unpainted voxels mean.
  const ApplyResult r = s.load(sphere());
  CHECK(r.fullRefresh);
  CHECK(s.digest() == digest(sphere()));
  CHECK_FALSE(s.canUndo());
}

TEST_CASE("session paint: refusals name the field and change nothing", "[session][paint][errors]") {
  Session s(sphere());
  const std::uint64_t start = s.digest();
  PaintSettings bad = red();
  bad.hardness = 1;
  requireError([&] { s.beginPaint(bad); }, protocol::RpcCode::InvalidParams, "hardness");
  bad = red(1e9);
  requireError([&] { s.beginPaint(bad); }, protocol::RpcCode::InvalidParams, "radius");
  bad = red();
  bad.strength = std::nan("");
  requireError([&] { s.beginPaint(bad); }, protocol::RpcCode::InvalidParams, "strength");
  CHECK(s.openStrokes() == 0);
  const StrokeId id = s.beginPaint(red());
  requireError([&] { s.strokeDabs(id, centres({kSide, Vec3{std::nan(""), 0, 0}}), ThreadPool::serial()); },
               protocol::RpcCode::InvalidParams, "dabs[1].center");
  requireError([&] { s.strokeDabs(id, centres({kSide, Vec3{5000, 0, 0}}), ThreadPool::serial()); },
               protocol::RpcCode::EngineRefused, "dabs[1].center");
  requireError([&] { s.strokeDabs(id, {Dab{kSide, 2.0}}, ThreadPool::serial()); }, protocol::RpcCode::InvalidParams,
               "dabs[0].pressure");
  CHECK(s.digest() == start);
  CHECK(s.revision() == 0);
  CHECK(s.steps().empty());
}

TEST_CASE("session paint: csg_add with a colour paints what it adds, and its op object keeps the colour", "[session][paint][csg]") {
  protocol::CsgToolOp op;
  op.params.op = CsgOp::Add;
  op.params.center = kSide + Vec3{4, 0, 0};
  op.params.radius = 4;
  op.color = SrgbColor{20, 40, 220};
  Session s(sphere());
  REQUIRE(s.apply(op, ThreadPool::serial()).changed);
  // The new bump's outermost surface voxel, 4 vu beyond the sphere: the union's colour.
  const Int3 tip{int(std::lround(kC + kR + 8)), int(kC), int(kC)};
  CHECK(std::fabs(s.volume().at(tip)) < s.volume().band());
  CHECK(s.volume().texel(tip) == texelOf(Rgb8{20, 40, 220}));
  // The far side keeps the clay.
  CHECK(s.volume().texel({int(std::lround(kC - kR)), int(kC), int(kC)}) == texelOf(kClayColor));
  // The op object round-trips with its colour (the journal replays it so), and without one the
  // same union leaves another digest.
  const protocol::Op parsed = protocol::parseOp(protocol::toJson(protocol::Op(op)));
  CHECK(std::get<protocol::CsgToolOp>(parsed).color == op.color);
  Session again(sphere());
  again.apply(parsed, ThreadPool::serial());
  CHECK(again.digest() == s.digest());
  protocol::CsgToolOp plain = op;
  plain.color.reset();
  Session uncoloured(sphere());
  uncoloured.apply(plain, ThreadPool::serial());
  CHECK(uncoloured.digest() != s.digest());
  CHECK(uncoloured.volume().paintedBricks() == 0);
}
