#include "csg.hpp"

#include <algorithm>
#include <cmath>

#include "dense_grid.hpp"
#include "errors.hpp"
#include "paint.hpp"
#include "progress.hpp"
#include "redistance.hpp"
#include "shapes.hpp"

namespace marzipan {

namespace {

// Paints `color` into the band voxels of the changed bricks that fromTool (over region, x
// fastest) marks as the tool's: the header's rule.
void paintFromTool(const Volume& vol, std::vector<BrickChange>& changes, const Box& region,
                   const std::vector<std::uint8_t>& fromTool, Rgb8 color) {
  const Int3 rs = region.size();
  const Texel base = texelOf(vol.baseColor());
  for (BrickChange& c : changes) {
    if (!c.after.data) continue;
    std::shared_ptr<BrickPaint> now;
    for (int i = 0; i < kBrickVoxels; ++i) {
      const Int3 p = Bricks::origin(c.brick) + Bricks::local(i);
      if (!region.contains(p) || !(std::fabs(c.after.data->v[i]) < vol.band())) continue;
      const Int3 r = p - region.lo;
      if (!fromTool[std::size_t(r.x) + std::size_t(rs.x) * (std::size_t(r.y) + std::size_t(rs.y) * std::size_t(r.z))])
        continue;
      const Texel had = texelSoFar(now.get(), c.after.paint.get(), base, i);
      const Texel t = tinted(had, color, 1);
      if (t == had) continue;
      setTexel(now, c.after.paint.get(), base, i, t);
    }
    if (now) c.after.paint = vol.canonicalPaint(std::move(now));
  }
}

}  // namespace

double toolDistance(const CsgParams& p, Vec3 x) {
  switch (p.shape) {
    case ToolShape::Sphere:
      return sdf::sphere(x, p.center, p.radius);
    case ToolShape::Box:
      return sdf::box(x, p.center, {p.radius, p.radius, p.radius});
    case ToolShape::Cylinder:
      return sdf::cylinder(x, p.center, p.radius, p.radius, p.axis);
  }
  return 0;
}

Edit applyCsg(Volume& vol, const CsgParams& p, ThreadPool& pool, std::optional<Rgb8> color) {
  if (!isFinite(p.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  requireRange(p.radius, 0.5, kMaxDomainSide, "radius");
  requireRange(p.blend, 0, p.radius, "blend");
  if (p.axis < 0 || p.axis > 2) throw EngineError(ErrorKind::InvalidArgument, "axis", "must be 0, 1 or 2");
  const float band = vol.band();
  // Every voxel whose value can change: the tool's bounding box grown by band and blend.
  const double reach = p.radius + band + p.blend + 1;
  const Box toolBox = boxAround(p.center, {reach, reach, reach});
  const Box region = toolBox.intersect(vol.domain());
  if (region.empty())
    throw EngineError(ErrorKind::OutOfDomain, "center", "the tool lies outside the volume");

  // The caller's Progress (progress.hpp): one unit for the call, checked per z-slice and
  // throughout the redistancing; a cancelled call stops before it writes anything to vol.
  Progress* const progress = Progress::current();
  const ProgressShare share{progress, 1};
  const int margin = int(std::ceil(band)) + 1;
  DenseGrid g;
  g.gatherFrom(vol, region.grown(margin), share.part(0.1));
  // With a colour: whether each voxel of the region takes its value from the tool.
  std::vector<std::uint8_t> fromTool(color ? std::size_t(region.voxels()) : 0);
  std::size_t k = 0;
  for (int z = region.lo.z; z < region.hi.z; ++z) {
    share.check();
    for (int y = region.lo.y; y < region.hi.y; ++y)
      for (int x = region.lo.x; x < region.hi.x; ++x) {
        const std::size_t i = g.index({x, y, z});
        const double d = g.v[i];
        const double t = toolDistance(p, {double(x), double(y), double(z)});
        double r = d;
        bool tool = false;
        switch (p.op) {
          case CsgOp::Add: r = sdf::smoothMin(d, t, p.blend); tool = t < d; break;
          case CsgOp::Subtract: r = sdf::smoothMax(d, -t, p.blend); tool = -t > d; break;
          case CsgOp::Intersect: r = sdf::smoothMax(d, t, p.blend); tool = t > d; break;
        }
        if (color) fromTool[k++] = tool;
        // Beyond the band only the sign matters (those voxels are marched afresh; on the side
        // kept exact both terms lie within it), and clamped they stay off the band list.
        g.v[i] = float(std::clamp(r, -double(band), double(band)));
      }
  }
  share.advance(0.2);
  // Outside the tool's reach max(d, t) is air: the march must not continue from the old field
  // there, and every brick outside the region is cleared (below, once nothing can stop).
  if (p.op == CsgOp::Intersect)
    for (std::size_t i = 0; i < g.v.size(); ++i)
      if (!region.contains(g.point(i))) g.v[i] = band;
  // min/max of two exact distances is exact on one side: outside a union, inside an
  // intersection or difference. Re-marching that side would only add the marcher's error
  // (up to 0.3 vu around the tool's convex edges); a blend is exact on neither side.
  RedistanceOptions opt;
  if (p.blend == 0) opt.exactSide = p.op == CsgOp::Add ? +1 : -1;
  opt.progress = share.part(0.6);
  redistanceRegion(g, region, band, Outside::Source, opt, pool);
  share.check();  // the last check: nothing below stops part way
  Edit e;
  if (p.op == CsgOp::Intersect) e.append(vol.clearOutside(region), vol.domain());
  std::vector<BrickChange> changes = vol.diff(region, g.v.data(), g.box);
  vol.extendChannels(changes);
  if (color) paintFromTool(vol, changes, region, fromTool, *color);
  vol.publish(changes, true);
  e.append(changes, region);
  share.advance(0.1);
  return e;
}

}  // namespace marzipan
