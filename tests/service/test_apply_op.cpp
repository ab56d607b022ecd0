// applyOp (server/service/apply_op.cpp): each operation object does exactly what the direct
// engine call does, checked by digests of two copies of one volume, and engine errors pass
// through unchanged. The cost of a stroke message counts the scan of its remembered dabs.
#include <catch2/catch.hpp>

#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"

using namespace marzipan;
using nlohmann::json;

namespace {

constexpr int kN = 48;
constexpr double kC = (kN - 1) / 2.0;
const double kSurface = kC + 0.35 * kN;  // the sphere's surface along +x

const Volume& startingSphere() {
  static const Volume sphere = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return sphere;
}

// Applies `op` through applyOp and `direct` to a second copy; both must change the volume
// the same way, and change it.
void requireSameAsEngine(const json& op, const std::function<Edit(Volume&, ThreadPool&)>& direct) {
  INFO(op.dump());
  ThreadPool pool(2);
  Volume viaOp = startingSphere();
  Volume viaEngine = startingSphere();
  const Edit a = service::applyOp(viaOp, protocol::parseOp(op), pool);
  const Edit b = direct(viaEngine, pool);
  CHECK(digest(viaOp) == digest(viaEngine));
  CHECK(digest(viaOp) != digest(startingSphere()));
  CHECK(a.changes.size() == b.changes.size());
  CHECK(a.region.lo == b.region.lo);
  CHECK(a.region.hi == b.region.hi);
}

}  // namespace

TEST_CASE("applyOp: brushes call the engine's brush tools", "[apply_op]") {
  const Vec3 c{kSurface, kC, kC};
  const json center = {c.x, c.y, c.z};
  const BrushParams p{c, 6, 0.75};
  requireSameAsEngine({{"tool", "add_blob"}, {"center", center}, {"radius", 6}, {"strength", 0.75}},
                      [&](Volume& v, ThreadPool& pool) { return addBlob(v, p, pool); });
  requireSameAsEngine({{"tool", "remove_blob"}, {"center", center}, {"radius", 6}, {"strength", 0.75}},
                      [&](Volume& v, ThreadPool& pool) { return removeBlob(v, p, pool); });
  requireSameAsEngine({{"tool", "smooth"}, {"center", center}, {"radius", 6}, {"strength", 0.75}},
                      [&](Volume& v, ThreadPool& pool) { return smooth(v, p, pool); });
  requireSameAsEngine({{"tool", "sharpen"}, {"center", center}, {"radius", 6}, {"strength", 0.75}},
                      [&](Volume& v, ThreadPool& pool) { return sharpen(v, p, pool); });
  // Defaults: radius 8, strength 1.
  requireSameAsEngine({{"tool", "add_blob"}, {"center", center}},
                      [&](Volume& v, ThreadPool& pool) { return addBlob(v, {c, 8, 1}, pool); });
}

TEST_CASE("applyOp: global smoothing calls mean curvature flow", "[apply_op]") {
  requireSameAsEngine({{"op", "smooth"}, {"global", true}, {"iterations", 2}, {"strength", 0.5}},
                      [](Volume& v, ThreadPool& pool) { return meanCurvatureFlow(v, 2, 0.5, pool); });
  requireSameAsEngine({{"tool", "smooth"}, {"global", true}, {"iterations", 1}},
                      [](Volume& v, ThreadPool& pool) { return meanCurvatureFlow(v, 1, 1, pool); });
}

TEST_CASE("applyOp: CSG tools call applyCsg", "[apply_op]") {
  const json center = {kSurface, kC, kC};
  const auto csg = [](CsgOp op, ToolShape shape, double radius, int axis, double blend) {
    CsgParams p;
    p.op = op;
    p.shape = shape;
    p.center = {kSurface, kC, kC};
    p.radius = radius;
    p.axis = axis;
    p.blend = blend;
    return [p](Volume& v, ThreadPool& pool) { return applyCsg(v, p, pool); };
  };
  requireSameAsEngine({{"tool", "csg_add"}, {"shape", "sphere"}, {"center", center}, {"radius", 5}},
                      csg(CsgOp::Add, ToolShape::Sphere, 5, 1, 0));
  requireSameAsEngine({{"tool", "csg_subtract"}, {"shape", "box"}, {"center", center}, {"radius", 4}, {"blend", 1.5}},
                      csg(CsgOp::Subtract, ToolShape::Box, 4, 1, 1.5));
  requireSameAsEngine({{"tool", "csg_intersect"},
                       {"shape", "cylinder"},
                       {"center", {kC, kC, kC}},
                       {"radius", 15},
                       {"axis", "z"}},
                      [](Volume& v, ThreadPool& pool) {
                        CsgParams p;
                        p.op = CsgOp::Intersect;
                        p.shape = ToolShape::Cylinder;
                        p.center = {kC, kC, kC};
                        p.radius = 15;
                        p.axis = 2;
                        return applyCsg(v, p, pool);
                      });
  requireSameAsEngine(
      {{"tool", "csg_add"}, {"shape", "cylinder"}, {"center", center}, {"radius", 3}, {"axis", "x"}, {"blend", 1}},
      csg(CsgOp::Add, ToolShape::Cylinder, 3, 0, 1));
}

TEST_CASE("applyOp: morphology calls erode, dilate, open and close", "[apply_op]") {
  requireSameAsEngine({{"op", "morph"}, {"kind", "erode"}, {"radius", 1.5}},
                      [](Volume& v, ThreadPool& pool) { return erode(v, 1.5, pool); });
  requireSameAsEngine({{"op", "morph"}, {"kind", "dilate"}, {"radius", 1.5}},
                      [](Volume& v, ThreadPool& pool) { return dilate(v, 1.5, pool); });
  // A pure sphere survives open and close almost unchanged, but not bit for bit.
  requireSameAsEngine({{"op", "morph"}, {"kind", "open"}, {"radius", 2}},
                      [](Volume& v, ThreadPool& pool) { return openSolid(v, 2, pool); });
  requireSameAsEngine({{"op", "morph"}, {"kind", "close"}, {"radius", 2}},
                      [](Volume& v, ThreadPool& pool) { return closeSolid(v, 2, pool); });
}

TEST_CASE("applyOp: the result does not depend on the thread count", "[apply_op]") {
  const protocol::Op op = protocol::parseOp(json{{"tool", "add_blob"}, {"center", {kSurface, kC, kC}}, {"radius", 10}});
  Volume one = startingSphere();
  Volume two = startingSphere();
  ThreadPool serialPool(1), pairPool(2);
  service::applyOp(one, op, serialPool);
  service::applyOp(two, op, pairPool);
  CHECK(digest(one) == digest(two));
}

TEST_CASE("applyOp: engine errors propagate unchanged and leave the volume as it was", "[apply_op]") {
  Volume v = startingSphere();
  const std::uint64_t before = digest(v);
  const protocol::Op outside =
      protocol::parseOp(json{{"tool", "add_blob"}, {"center", {500, 500, 500}}, {"radius", 8}});
  try {
    service::applyOp(v, outside, ThreadPool::serial());
    FAIL("an op outside the domain was applied");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::OutOfDomain);
    CHECK(e.field() == "center");
  }
  const protocol::Op csgOutside = protocol::parseOp(
      json{{"tool", "csg_add"}, {"shape", "sphere"}, {"center", {-300, 0, 0}}, {"radius", 8}});
  CHECK_THROWS_AS(service::applyOp(v, csgOutside, ThreadPool::serial()), EngineError);
  CHECK(digest(v) == before);
}

TEST_CASE("strokeDabVoxels: the scan of remembered dabs is in a stroke message's cost", "[apply_op]") {
  // Issue 31 item 8: where a stroke's remembered dabs are weaker than a message's dab, each
  // voxel the dab moves scans every remembered dab over it; the estimate left that out, so one
  // dab cost 10-25 times its estimate. Here 4096 weak dabs lie where the message's dab lands.
  // What the scan costs in time is the benchmark stroke_memory_scan's (tests/bench, the same
  // dabs): 2026-11-29 on the 2-core VM, 29-93 times the dab alone between runs on the loaded
  // machine. This checks the estimate against that range rather than timing it here, where a
  // loaded machine decides the ratio: at least the smallest ratio measured, and not orders of
  // magnitude more than the largest.
  const Volume sphere = makeSolid(SolidKind::Sphere, {96, 96, 96});
  const StrokeSettings st{Brush::AddBlob, 12, 1};
  const Vec3 at{47.5 + 0.35 * 96, 47.5, 47.5};
  std::vector<StrokeDab> memory;
  for (int i = 0; i < int(service::Session::kMaxStrokeMemory); ++i)
    memory.push_back({{at.x, at.y + (i % 16) * 0.25, at.z + (i / 16 % 16) * 0.25}, 0.02});
  const double plain = service::strokeDabVoxels(sphere, st.radius, 1, 1, {});
  const double estimate = service::strokeDabVoxels(sphere, st.radius, 1, 1, memory);
  CHECK(plain == service::brushVoxels(sphere, st.radius));
  CHECK(service::rememberedOverlap(memory, st.radius + sphere.band() + 1) == memory.size());
  INFO("estimate " << plain << " -> " << estimate << " voxels");
  CHECK(estimate / plain >= 29);
  CHECK(estimate / plain <= 10 * 93);
  // Remembered dabs far from each other (70 vu apart, reach 15): no voxel is under two.
  std::vector<StrokeDab> spread;
  for (int i = 0; i < 64; ++i) spread.push_back({{double(i % 4) * 70, double(i / 4 % 4) * 70, double(i / 16) * 70}, 0.02});
  CHECK(service::rememberedOverlap(spread, 15) == 1);
  spread.push_back({{5, 5, 5}, 0.02});
  CHECK(service::rememberedOverlap(spread, 15) == 2);
}
