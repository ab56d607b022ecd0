// Warp strokes of a Session (session.cpp warpDabs, apply_op.cpp applyWarpStroke; PROTOCOL.md,
// warp strokes): the first dab is the anchor, the later ones the pointer. Checked against exact
// answers: the engine's own warp of the starting volume by the contract's d, angle, factor and
// amount, bit for bit; the grabbed surface where the pointer is; any grouping of the messages;
// one undo step back to the starting digest; refusals that change nothing.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"
#include "session_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::centres;
using marzipan::service::testing::requireError;
using protocol::WarpTool;

namespace {

constexpr int kN = 64;
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;
const Vec3 kCentre{kC, kC, kC};
// The sphere's surface point on +x, and its outward normal.
const Vec3 kAnchor{kC + kR, kC, kC};

const Volume& sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

WarpStroke settings(WarpTool tool, double radius, std::optional<Vec3> direction = std::nullopt, double strength = 1) {
  WarpStroke w;
  w.tool = tool;
  w.radius = radius;
  w.strength = strength;
  w.direction = direction;
  return w;
}

// The pointer's way from the anchor to `to`, in n equal steps (the anchor first).
std::vector<Vec3> drag(Vec3 from, Vec3 to, int n) {
  std::vector<Vec3> out{from};
  for (int i = 1; i <= n; ++i) out.push_back(from + (to - from) * (double(i) / n));
  return out;
}

}  // namespace

TEST_CASE("session warp: a grab lands the anchor on the pointer and is the engine's grab of the start", "[session][warp]") {
  ThreadPool pool(2);
  Session s(sphere());
  const std::uint64_t start = s.digest();
  const StrokeId id = s.beginWarp(settings(WarpTool::Grab, 12));
  const Vec3 d{6, 4, 0};
  const ApplyResult a = s.strokeDabs(id, centres(drag(kAnchor, kAnchor + d, 5)), pool);
  CHECK(a.changed);
  CHECK(a.anchored);
  // The surface point on the drag's line: where the anchor went, within 0.25 vu of anchor + d.
  const std::optional<Vec3> hit = pickSurface(s.volume(), kAnchor + d * 2.0, d * -1.0);
  REQUIRE(hit);
  CHECK(length(*hit - (kAnchor + d)) <= kWarpAnchorTolerance);
  // Exactly the engine's grab of the starting volume by d.
  Volume expected = sphere();
  grab(expected, sphere(), kAnchor, d, 12, pool);
  CHECK(s.digest() == digest(expected));
  CHECK(digest(s.volume()) == digest(expected));
  s.endStroke(id);
  // One step, named for the tool; undo restores the start.
  REQUIRE(s.steps().size() == 1);
  CHECK(s.steps()[0].tool == "grab");
  CHECK(s.undo().changed);
  CHECK(s.digest() == start);
  CHECK(digest(s.volume()) == start);
}

TEST_CASE("session warp: anchored strokes give the same volume however their messages are grouped", "[session][warp]") {
  ThreadPool pool(2);
  for (const WarpTool tool : {WarpTool::Grab, WarpTool::ElasticGrab, WarpTool::Twist, WarpTool::LocalScale, WarpTool::Pinch}) {
    INFO(protocol::nameOf(protocol::kWarpToolNames, tool));
    const std::vector<Vec3> dabs = drag(kAnchor, kAnchor + Vec3{3, 7, -2}, 10);
    Session one(sphere()), many(sphere());
    const StrokeId a = one.beginWarp(settings(tool, 10));
    one.strokeDabs(a, centres(dabs), pool);
    const StrokeId b = many.beginWarp(settings(tool, 10));
    // The anchor alone, then each pointer point in its own message (10 messages after it).
    for (const Vec3 p : dabs) many.strokeDabs(b, centres({p}), pool);
    CHECK(one.digest() == many.digest());
    CHECK(one.digest() != digest(sphere()));
    // Folded into one step each.
    CHECK(one.steps().size() == 1);
    CHECK(many.steps().size() == 1);
  }
}

TEST_CASE("session warp: twist, scale and pinch are the engine's warps by the contract's amounts, signed by direction",
          "[session][warp]") {
  ThreadPool pool(2);
  const double r = 10;
  const Vec3 normal{1, 0, 0};
  const Vec3 right{0, 0, 3};  // any length: only its direction counts
  for (const double sign : {1.0, -1.0}) {
    // The pointer 0.8 radii along +-direction, and some way across it, which does not count.
    const Vec3 p = kAnchor + Vec3{0, 0, sign * 0.8 * r} + Vec3{0, 2.5, 0};
    const double s = sign * 0.8;
    const auto warped = [&](WarpTool tool) {
      Session session(sphere());
      const StrokeId id = session.beginWarp(settings(tool, r, right));
      session.strokeDabs(id, centres({kAnchor, p}), pool);
      return session.digest();
    };
    INFO("sign " << sign);
    Volume twisted = sphere();
    twist(twisted, sphere(), kAnchor, normal, s * std::numbers::pi / 2, r, pool);
    CHECK(warped(WarpTool::Twist) == digest(twisted));
    Volume scaled = sphere();
    localScale(scaled, sphere(), kAnchor, std::exp2(s), r, pool);
    CHECK(warped(WarpTool::LocalScale) == digest(scaled));
    // Scaling a convex surface up about a point of it adds material there, down takes some.
    CHECK((insideVolume(scaled) > insideVolume(sphere())) == (sign > 0));
    Volume pinched = sphere();
    pinch(pinched, sphere(), kAnchor, normal, s / 2, r, pool);
    CHECK(warped(WarpTool::Pinch) == digest(pinched));
  }
  // Without a direction the amount is the drag's length in radii: 2 radii scale by 4.
  Session session(sphere());
  const StrokeId id = session.beginWarp(settings(WarpTool::LocalScale, r));
  session.strokeDabs(id, centres({kAnchor, kAnchor + Vec3{0, -2 * r, 0}}), pool);
  Volume scaled = sphere();
  localScale(scaled, sphere(), kAnchor, 4, r, pool);
  CHECK(session.digest() == digest(scaled));
}

TEST_CASE("session warp: strength scales the drag, and the clamps are the engine's limits", "[session][warp]") {
  ThreadPool pool(2);
  Session half(sphere());
  const StrokeId a = half.beginWarp(settings(WarpTool::Grab, 12, std::nullopt, 0.5));
  half.strokeDabs(a, centres({kAnchor, kAnchor + Vec3{8, 0, 0}}), pool);
  Volume expected = sphere();
  grab(expected, sphere(), kAnchor, {4, 0, 0}, 12, pool);
  CHECK(half.digest() == digest(expected));
  // A twist dragged 10 radii turns by the engine's most, 2 pi (s = 4 would be the same).
  Session far(sphere());
  const StrokeId b = far.beginWarp(settings(WarpTool::Twist, 4));
  far.strokeDabs(b, centres({kAnchor, kAnchor + Vec3{0, 40, 0}}), pool);
  Volume turned = sphere();
  twist(turned, sphere(), kAnchor, {1, 0, 0}, 2 * std::numbers::pi, 4, pool);
  CHECK(far.digest() == digest(turned));
}

TEST_CASE("session warp: a snake hook composes its moves along the path", "[session][warp]") {
  ThreadPool pool(2);
  Session s(sphere());
  const StrokeId id = s.beginWarp(settings(WarpTool::SnakeHook, 6));
  const std::vector<Vec3> path = drag(kAnchor, kAnchor + Vec3{6, 6, 0}, 4);
  s.strokeDabs(id, centres({path[0], path[1], path[2]}), pool);
  s.strokeDabs(id, centres({path[3], path[4]}), pool);
  // The engine's moves one after the other, each from where the last ended.
  Volume expected = sphere();
  for (std::size_t i = 1; i < path.size(); ++i) snakeHook(expected, path[i - 1], path[i], 6, pool);
  CHECK(s.digest() == digest(expected));
  CHECK(s.steps().size() == 1);
  CHECK(s.steps()[0].tool == "snake_hook");
}

TEST_CASE("session warp: a pinch path is the engine's pinchAlong from dab to dab, pressure scaling each move",
          "[session][warp][pinch_path]") {
  ThreadPool pool(2);
  Session s(sphere());
  const double strength = 0.8;
  const StrokeId id = s.beginWarp(settings(WarpTool::PinchAlong, 6, std::nullopt, strength));
  // Along the sphere's equator from +x towards +y, 2.2 vu a dab, with pressures.
  std::vector<Vec3> path;
  for (int i = 0; i <= 6; ++i) path.push_back(kCentre + Vec3{std::cos(0.1 * i), std::sin(0.1 * i), 0} * kR);
  const std::vector<double> pressure{1, 0.5, 1, 0.25, 1, 0.75, 1};
  std::vector<Dab> dabs;
  for (std::size_t i = 0; i < path.size(); ++i) dabs.push_back(Dab{path[i], pressure[i]});
  s.strokeDabs(id, {dabs.begin(), dabs.begin() + 3}, pool);
  s.strokeDabs(id, {dabs.begin() + 3, dabs.end()}, pool);
  s.endStroke(id);
  // The engine's moves one after the other, each at strength times its end's pressure, towards
  // the plane along the normal of the volume (as the moves before left it) at the move's end.
  Volume expected = sphere();
  for (std::size_t i = 1; i < path.size(); ++i)
    pinchAlong(expected, path[i - 1], path[i], normalized(expected.gradient(path[i])), strength * pressure[i], 6, pool);
  CHECK(s.digest() == digest(expected));
  CHECK(digest(expected) != digest(sphere()));
  REQUIRE(s.steps().size() == 1);
  CHECK(s.steps()[0].tool == "pinch_path");
  // One undo step takes it all back.
  s.undo();
  CHECK(s.digest() == digest(sphere()));
}

TEST_CASE("session warp: a pinch path refuses a dab outside the volume, changing nothing, and costs each move",
          "[session][warp][pinch_path]") {
  ThreadPool pool(2);
  Session s(sphere());
  const StrokeId id = s.beginWarp(settings(WarpTool::PinchAlong, 6));
  const std::uint64_t d0 = s.digest(), r0 = s.revision();
  testing::requireError([&] { s.strokeDabs(id, centres({kAnchor, kAnchor + Vec3{0, 2, 0}, Vec3{kN + 1.0, kC, kC}}), pool); },
                        protocol::RpcCode::EngineRefused, "dabs.center");
  CHECK(s.digest() == d0);
  CHECK(s.revision() == r0);
  // Each move is a call; a move of 60 vu at radius 6 goes in ceil(60 / 48) = 2 pieces; a pressure
  // of 0 moves nothing.
  const Volume big(Int3{256, 256, 256});
  const Vec3 a{128, 128, 128};
  const WarpStroke w = settings(WarpTool::PinchAlong, 6);
  const std::vector<Vec3> moves{a + Vec3{2, 0, 0}, a + Vec3{4, 0, 0}, a + Vec3{64, 0, 0}};
  CHECK(warpStrokeCost(big, w, a, moves).passes == 4);
  const std::vector<double> none{1, 0, 1};
  CHECK(warpStrokeCost(big, w, a, moves, none).passes == 3);
  // An anchor not known yet (a ray's far stand-in) costs as the volume's far corner, bounded.
  const OpCost far = warpStrokeCost(big, w, Vec3{1e9, 1e9, 1e9}, std::vector<Vec3>{a});
  CHECK(far.passes == std::ceil(std::sqrt(3.0) * 127 / 48));
}

TEST_CASE("session warp: another change during a stroke is kept, the stroke goes on from it", "[session][warp]") {
  ThreadPool pool(2);
  Session s(sphere());
  const StrokeId id = s.beginWarp(settings(WarpTool::Grab, 8));
  s.strokeDabs(id, centres({kAnchor, kAnchor + Vec3{2, 0, 0}}), pool);
  // A blob on the far side, then the grab goes on: the blob stays.
  const Vec3 far{kC - kR, kC, kC};
  s.apply(protocol::BrushOp{protocol::BrushTool::AddBlob, BrushParams{far, 4, 1}}, pool);
  const double blob = s.volume().sample(far + Vec3{-0.5, 0, 0});
  s.strokeDabs(id, centres({kAnchor + Vec3{4, 0, 0}}), pool);
  CHECK(s.volume().sample(far + Vec3{-0.5, 0, 0}) == blob);
  CHECK(blob < 0);
  const std::optional<Vec3> hit = pickSurface(s.volume(), kAnchor + Vec3{12, 0, 0}, {-1, 0, 0});
  REQUIRE(hit);
  CHECK(std::abs(hit->x - (kAnchor.x + 4)) <= 2 * kWarpAnchorTolerance);
}

TEST_CASE("session warp: an anchor picked where the surface was is taken at the surface point nearest it",
          "[session][warp]") {
  // A client picks on splats another sculptor's edit has since moved: 2.5 vu off the sphere
  // (past the 2 vu taken as given, within the band of 3).
  ThreadPool pool(2);
  const Vec3 stale = kAnchor + normalized(Vec3{1, 0.3, 0}) * 2.5;
  const Vec3 pointer = stale + Vec3{0, 5, 0};
  Session s(sphere());
  const StrokeId id = s.beginWarp(settings(WarpTool::Grab, 10));
  const ApplyResult a = s.strokeDabs(id, centres({stale, pointer}), pool);
  REQUIRE(a.anchored);
  REQUIRE(a.changed);
  // The anchor taken (the journal's first dab) is on the sphere, on the stale point's radius.
  REQUIRE(a.hits.size() == 2);
  REQUIRE(a.hits[0]);
  const Vec3 taken = *a.hits[0];
  CHECK(std::abs(length(taken - kCentre) - kR) <= 0.05);
  CHECK(length(normalized(taken - kCentre) - normalized(stale - kCentre)) <= 1e-3);
  // Exactly the engine's grab from that point to the pointer, and a stroke anchored there
  // (a replay of the journal) gives the same bits.
  Volume expected = sphere();
  grab(expected, sphere(), taken, pointer - taken, 10, pool);
  CHECK(s.digest() == digest(expected));
  Session replay(sphere());
  const StrokeId r = replay.beginWarp(settings(WarpTool::Grab, 10));
  replay.strokeDabs(r, centres({taken, pointer}), pool);
  CHECK(replay.digest() == s.digest());
  // A point as far as the band, or farther, is still refused: nothing says where its surface went.
  Session far(sphere());
  const StrokeId f = far.beginWarp(settings(WarpTool::Grab, 10));
  requireError([&] { far.strokeDabs(f, centres({kAnchor + Vec3{3, 0, 0}, pointer}), pool); }, protocol::RpcCode::InvalidParams,
               "center");
  CHECK(far.digest() == digest(sphere()));
}

TEST_CASE("session warp: an anchor is never carried out of the grid, so its journal replays", "[session][warp]") {
  // A sphere whose surface crosses x = -0.5, just outside the grid: voxel 0 reads -0.5, and the
  // voxels beyond the face read +band, so the zero set of the samples lies at x = -1/7. A pick
  // at x = 1.8 (-2.3) was carried there and taken; the journal's replay of that anchor was then
  // refused as outside the domain (a session that could no longer be loaded).
  ThreadPool pool(2);
  const Vec3 c{12, 16, 16};
  const Volume cut = makeSphere({32, 32, 32}, c, 12.5);
  const Vec3 pick{1.8, 16, 16};
  REQUIRE(cut.sample(pick) < -kMaxWarpAnchorDistance);
  REQUIRE(cut.towardSurface(pick, kAnchorSnapSteps).x < 0);
  Session s(cut);
  const StrokeId id = s.beginWarp(settings(WarpTool::Grab, 6));
  requireError([&] { s.strokeDabs(id, centres({pick, pick + Vec3{0, 4, 0}}), pool); }, protocol::RpcCode::InvalidParams,
               "center");
  CHECK(s.digest() == digest(cut));
  // The surface point inside the grid is taken as given.
  const ApplyResult a = s.strokeDabs(id, centres({Vec3{0, 16, 16}, Vec3{0, 20, 16}}), pool);
  CHECK(a.anchored);
  CHECK(a.changed);
}

TEST_CASE("session warp: refusals name the field and change nothing", "[session][warp]") {
  ThreadPool pool(2);
  using C = protocol::RpcCode;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Session s(sphere());
  requireError([&] { s.beginWarp(settings(WarpTool::Grab, 0.5)); }, C::InvalidParams, "radius");
  requireError([&] { s.beginWarp(settings(WarpTool::Grab, 65)); }, C::InvalidParams, "radius");
  requireError([&] { s.beginWarp(settings(WarpTool::ElasticGrab, 22)); }, C::InvalidParams, "radius");
  requireError([&] { s.beginWarp(settings(WarpTool::Twist, 8, Vec3{0, 0, 0})); }, C::InvalidParams, "direction");
  requireError([&] { s.beginWarp(settings(WarpTool::Twist, 8, Vec3{nan, 0, 1})); }, C::InvalidParams, "direction");
  const StrokeId id = s.beginWarp(settings(WarpTool::Grab, 8));
  const std::uint64_t d0 = s.digest(), r0 = s.revision();
  // An anchor off the surface (3 vu out), NaN, outside the domain; a ray after the anchor.
  requireError([&] { s.strokeDabs(id, centres({kAnchor + Vec3{3, 0, 0}, kAnchor}), pool); }, C::InvalidParams, "center");
  requireError([&] { s.strokeDabs(id, centres({Vec3{nan, 0, 0}}), pool); }, C::InvalidParams, "dabs[0].center");
  requireError([&] { s.strokeDabs(id, centres({Vec3{-5, kC, kC}}), pool); }, C::EngineRefused, "center");
  requireError([&] { s.strokeDabs(id, {Dab{kAnchor}, Dab{Ray{{0, 0, 0}, {1, 1, 1}}}}, pool); }, C::InvalidParams,
               "dabs[1].ray");
  CHECK(s.digest() == d0);
  CHECK(s.revision() == r0);
  // None of them took the anchor: the next message's first dab is it.
  const ApplyResult a = s.strokeDabs(id, centres({kAnchor, kAnchor + Vec3{2, 0, 0}}), pool);
  CHECK(a.anchored);
  CHECK(a.changed);
  // A ray that misses takes no anchor and changes nothing.
  const StrokeId other = s.beginWarp(settings(WarpTool::Grab, 8));
  const ApplyResult missed = s.strokeDabs(other, {Dab{Ray{{0, 0, 0}, {-1, 0, 0}}}, Dab{kAnchor}}, pool);
  CHECK_FALSE(missed.changed);
  CHECK_FALSE(missed.anchored);
  CHECK(missed.missed == 1);
}

TEST_CASE("session warp: a cost grows with the drag and caps at the engine's travel", "[session][warp]") {
  const WarpStroke w = settings(WarpTool::Grab, 20);
  const Volume big(Int3{256, 256, 256});
  const Vec3 a{128, 128, 128};
  const std::vector<Vec3> near{a + Vec3{20, 0, 0}}, farther{a + Vec3{60, 0, 0}}, beyond{a + Vec3{1000, 0, 0}};
  const double c20 = warpStrokeCost(big, w, a, near).voxels, c60 = warpStrokeCost(big, w, a, farther).voxels;
  CHECK(c60 > 1.5 * c20);
  // Past 8 radii the drag is clamped: the cost of 1000 vu is that of 160.
  const std::vector<Vec3> most{a + Vec3{160, 0, 0}};
  CHECK(warpStrokeCost(big, w, a, beyond).voxels == Approx(warpStrokeCost(big, w, a, most).voxels));
  // A snake hook costs each of its moves.
  const WarpStroke hook = settings(WarpTool::SnakeHook, 8);
  const std::vector<Vec3> path{a + Vec3{2, 0, 0}, a + Vec3{4, 0, 0}, a + Vec3{6, 0, 0}};
  const OpCost moves = warpStrokeCost(big, hook, a, path);
  CHECK(moves.passes == 3);
  CHECK(moves.voxels == Approx(3 * warpStrokeCost(big, hook, a, std::vector<Vec3>{a + Vec3{2, 0, 0}}).voxels));
}

TEST_CASE("session warp: a call's cost takes its sub-steps from the engine's bound of |grad v|", "[session][warp]") {
  // Pairs of calls over the same box (grab and snake hook of one move, the grab's radius the
  // snake hook's widest support, snakeHookSupportBound; elastic grab at two
  // volumes; the affine warps, whose box is the radius's, at two amounts; a pinch path's move at
  // two strengths) cost in the ratio of 1 + kWarpStepVoxels * ceil(bound / kWarpStretchPerStep),
  // the bound the engine's (level_set.hpp), which its calls take their sub-steps from.
  const Volume big(Int3{256, 256, 256});
  const Vec3 a{128, 128, 128};
  const auto cost = [&](const WarpStroke& w, Vec3 p) { return warpStrokeCost(big, w, a, std::vector<Vec3>{p}).voxels; };
  const auto work = [](double bound) { return 1 + kWarpStepVoxels * std::ceil(bound / kWarpStretchPerStep); };
  const auto ratio = [&](const WarpStroke& w1, Vec3 p1, const WarpStroke& w2, Vec3 p2) { return cost(w1, p1) / cost(w2, p2); };
  const Vec3 d{30, 0, 0};
  REQUIRE(snakeHookSupportBound(10) == 15);
  CHECK(ratio(settings(WarpTool::Grab, 15), a + d, settings(WarpTool::SnakeHook, 10), a + d) ==
        Approx(work(grabSlopeBound(30, 15)) / work(snakeHookSlopeBound(30, 10))).epsilon(1e-12));
  WarpStroke hard = settings(WarpTool::ElasticGrab, 8), soft = hard;
  soft.volume = 0;
  const Vec3 e{10, 0, 0};
  CHECK(ratio(hard, a + e, soft, a + e) ==
        Approx(work(elasticGrabSlopeBound(10, 8, 0.5)) / work(elasticGrabSlopeBound(10, 8, 0))).epsilon(1e-12));
  // Drags of 4 and 12 vu along the direction at radius 8: s = 0.5 and 1.5 radii.
  const Vec3 x{1, 0, 0}, near = a + Vec3{4, 0, 0}, far = a + Vec3{12, 0, 0};
  const double pi = std::numbers::pi;
  CHECK(ratio(settings(WarpTool::Twist, 8, x), far, settings(WarpTool::Twist, 8, x), near) ==
        Approx(work(twistSlopeBound(1.5 * pi / 2)) / work(twistSlopeBound(0.5 * pi / 2))).epsilon(1e-12));
  CHECK(ratio(settings(WarpTool::LocalScale, 8, x), far, settings(WarpTool::LocalScale, 8, x), near) ==
        Approx(work(localScaleSlopeBound(std::exp2(1.5))) / work(localScaleSlopeBound(std::exp2(0.5)))).epsilon(1e-12));
  CHECK(ratio(settings(WarpTool::Pinch, 8, x), far, settings(WarpTool::Pinch, 8, x), near) ==
        Approx(work(pinchSlopeBound(0.75)) / work(pinchSlopeBound(0.25))).epsilon(1e-12));
  CHECK(ratio(settings(WarpTool::PinchAlong, 6), a + e, settings(WarpTool::PinchAlong, 6, std::nullopt, 0.5), a + e) ==
        Approx(work(pinchAlongSlopeBound(10, 1, 6)) / work(pinchAlongSlopeBound(10, 0.5, 6))).epsilon(1e-12));
  // Each pair's calls take different sub-steps: the ratios say which bound was read.
  CHECK(work(grabSlopeBound(30, 15)) != work(snakeHookSlopeBound(30, 10)));
  CHECK(work(elasticGrabSlopeBound(10, 8, 0.5)) != work(elasticGrabSlopeBound(10, 8, 0)));
  CHECK(work(twistSlopeBound(1.5 * pi / 2)) != work(twistSlopeBound(0.5 * pi / 2)));
  CHECK(work(localScaleSlopeBound(std::exp2(1.5))) != work(localScaleSlopeBound(std::exp2(0.5))));
  CHECK(work(pinchSlopeBound(0.75)) != work(pinchSlopeBound(0.25)));
  CHECK(work(pinchAlongSlopeBound(10, 1, 6)) != work(pinchAlongSlopeBound(10, 0.5, 6)));
}
