// The speed of each brush tool (../level_set.hpp: Brush): the Motion strokeMotion gives it (F0
// and its scheme: constant-speed advection for add / remove blob, curvature flow for smooth /
// sharpen, with their time steps and sub-steps), the rules of its settings, and its one-dab
// entry point (addBlob ...: a stroke of one dab, stroke.cpp). Motion::speed is signed: > 0
// moves the surface outward (advection) or runs the flow forward in time (curvature). A new
// surface tool starts here (README.md says what else it needs).
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "engine/errors.hpp"
#include "engine/level_set/internal.hpp"

namespace marzipan::level_set {

namespace {

// The smoothing brush takes this many such steps per application: one step moves a groove of
// radius 4 by a few hundredths of a vu, invisible, so a sculptor needed many passes
// (tests/engine/level_set/test_stroke.cpp, "one smoothing application ... fills a groove").
constexpr int kSmoothSubsteps = 32;
// Sharpening runs the flow backwards; |L| <= 1 per voxel keeps noise from blowing up.
constexpr double kSharpenCurvatureLimit = 1.0;
// Crease's window reaches 0 at radius / this: its groove is as deep as remove blob's under the
// stroke and this much narrower at every depth (half as wide at half depth needs 2 or more).
constexpr double kCreaseNarrowing = 2.5;

}  // namespace

Motion strokeMotion(const StrokeSettings& st) {
  switch (st.tool) {
    case Brush::AddBlob:
    case Brush::Inflate:
    case Brush::Clay: return advection(st.strength);
    case Brush::RemoveBlob:
    case Brush::Crease: return advection(-st.strength);
    case Brush::Smooth: return curvatureFlow(st.strength, std::numeric_limits<double>::infinity(), kSmoothSubsteps);
    case Brush::Sharpen: return curvatureFlow(-st.strength, kSharpenCurvatureLimit);
    case Brush::Flatten:
    case Brush::Contrast: {
      Motion m = advection(st.tool == Brush::Flatten ? st.strength : -st.strength);
      m.towardsPlane = true;
      m.planePoint = st.plane->point;
      m.planeNormal = st.plane->normal;
      return m;
    }
  }
  throw EngineError(ErrorKind::InvalidArgument, "tool", "unknown brush tool");
}

double windowRadius(const StrokeSettings& st) {
  return st.tool == Brush::Crease ? st.radius / kCreaseNarrowing : st.radius;
}

double signedHeight(const StrokeSettings& st) {
  if (!st.height) return 0;
  return st.tool == Brush::RemoveBlob ? -*st.height : *st.height;
}

void checkToolDab(const StrokeSettings& st, const StrokeDab& d) {
  if (!st.height) return;
  if (st.tool == Brush::Inflate && d.normal != Vec3{})
    throw EngineError(ErrorKind::InvalidArgument, "normal", "inflate moves each point along its own normal: must be zero");
  if (st.tool == Brush::Clay && d.normal == Vec3{})
    throw EngineError(ErrorKind::InvalidArgument, "normal", "clay with a height needs the stroke's normal");
}

}  // namespace marzipan::level_set

namespace marzipan {

void checkStrokeSettings(const StrokeSettings& st) {
  requireRange(st.radius, 0.5, kMaxDomainSide, "radius");
  requireFinite(st.strength, "strength");
  if (!(st.strength > 0 && st.strength <= 1))
    throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  if (st.height) {
    if (st.tool != Brush::AddBlob && st.tool != Brush::RemoveBlob && st.tool != Brush::Inflate && st.tool != Brush::Clay)
      throw EngineError(ErrorKind::InvalidArgument, "height", "is only for add_blob, remove_blob, inflate and clay");
    const double most = std::min(st.radius * kMaxStrokeHeightPerRadius, kMaxStrokeHeight);
    if (!(std::isfinite(*st.height) && *st.height > 0 && *st.height <= most))
      throw EngineError(ErrorKind::InvalidArgument, "height", "must be in (0, min(radius / 2, 64)] vu");
  }
  const bool planar = brushUsesPlane(st.tool);
  if (planar != st.plane.has_value())
    throw EngineError(ErrorKind::InvalidArgument, "plane", planar ? "flatten and contrast need the stroke's plane"
                                                                   : "is only for flatten and contrast");
  if (st.plane && (!isFinite(st.plane->point) || !isFinite(st.plane->normal) ||
                   !(std::fabs(dot(st.plane->normal, st.plane->normal) - 1) <= 1e-6)))
    throw EngineError(ErrorKind::InvalidArgument, "plane", "must be a finite point and a unit normal");
}

Plane fitBrushPlane(const Volume& vol, Vec3 center, double radius) {
  requireRange(radius, 0.5, kMaxDomainSide, "radius");
  if (!isFinite(center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  // The voxels whose foot point may lie within the radius, and one more for the normals.
  const double reach = radius + vol.band() + 1;
  const Box inner = boxAround(center, {reach, reach, reach}).intersect(vol.domain());
  const Box box = inner.grown(1).intersect(vol.domain());
  if (inner.empty()) throw EngineError(ErrorKind::OutOfDomain, "center", "the tool's region lies outside the volume");
  std::vector<float> d(std::size_t(box.voxels()));
  vol.gather(box, d.data());
  const std::size_t sy = std::size_t(box.hi.x - box.lo.x), sz = sy * std::size_t(box.hi.y - box.lo.y);
  Vec3 sumPoint{}, sumNormal{};
  double sumWeight = 0;
  // The sums in index order, one thread: the plane does not depend on the pool.
  for (int z = inner.lo.z; z < inner.hi.z; ++z)
    for (int y = inner.lo.y; y < inner.hi.y; ++y)
      for (int x = inner.lo.x; x < inner.hi.x; ++x) {
        if (x == box.lo.x || y == box.lo.y || z == box.lo.z || x + 1 == box.hi.x || y + 1 == box.hi.y ||
            z + 1 == box.hi.z)
          continue;  // a normal needs both neighbours
        const std::size_t i = std::size_t(x - box.lo.x) + std::size_t(y - box.lo.y) * sy + std::size_t(z - box.lo.z) * sz;
        const double phi = d[i];
        const double weight = 1 - std::fabs(phi);
        if (!(weight > 0)) continue;
        const Vec3 n = normalized(Vec3{double(d[i + 1] - d[i - 1]), double(d[i + sy] - d[i - sy]),
                                       double(d[i + sz] - d[i - sz])});
        const Vec3 q = Vec3{double(x), double(y), double(z)} - n * phi;
        if (length(q - center) > radius) continue;
        sumPoint = sumPoint + q * weight;
        sumNormal = sumNormal + n * weight;
        sumWeight += weight;
      }
  if (!(sumWeight > 0) || !(length(sumNormal) > 0))
    throw EngineError(ErrorKind::InvalidArgument, "center", "no surface lies within the radius");
  return {sumPoint * (1 / sumWeight), normalized(sumNormal)};
}

namespace {

Edit applyBrush(Volume& vol, Brush tool, const BrushParams& p, ThreadPool& pool) {
  if (!isFinite(p.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  const StrokeDab dab{p.center, 1.0};
  return applyStroke(vol, {tool, p.radius, p.strength}, {&dab, 1}, {}, pool);
}

}  // namespace

Edit addBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::AddBlob, p, pool);
}

Edit removeBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::RemoveBlob, p, pool);
}

Edit smooth(Volume& vol, const BrushParams& p, ThreadPool& pool) { return applyBrush(vol, Brush::Smooth, p, pool); }

Edit sharpen(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::Sharpen, p, pool);
}

}  // namespace marzipan
