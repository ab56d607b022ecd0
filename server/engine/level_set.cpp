#include "level_set.hpp"

#include <cmath>
#include <limits>

#include "chunked_pass.hpp"
#include "dense_grid.hpp"
#include "errors.hpp"
#include "redistance.hpp"

namespace marzipan {

namespace {

// How the band moves during one application.
struct Motion {
  enum class Kind { Advect, Curvature };
  Kind kind = Kind::Advect;
  double speed = 0;      // s: signed; advection speed in vu per unit time, or curvature scale
  double dt = 0;         // time step of one sub-step
  int substeps = 1;
  bool windowed = false; // W(q) of the ROI around center/radius, else W = 1
  Vec3 center{};
  double radius = 0;
  double curvatureLimit = std::numeric_limits<double>::infinity();
};

// Advection: two sub-steps of dt |F| <= 0.5 vu (the CFL bound of the upwind scheme), so one
// application at speed 1 moves the surface 1 vu.
constexpr double kAdvectDt = 0.5;
constexpr int kAdvectSubsteps = 2;
// Curvature flow: one explicit step at the 7-point Laplacian's stability limit dt = 1/6.
constexpr double kCurvatureDt = 1.0 / 6.0;
// Sharpening runs the flow backwards; |L| <= 1 per voxel keeps noise from blowing up.
constexpr double kSharpenCurvatureLimit = 1.0;

Motion advection(double speed) {
  return {.kind = Motion::Kind::Advect, .speed = speed, .dt = kAdvectDt, .substeps = kAdvectSubsteps};
}

Motion curvatureFlow(double scale, double limit = std::numeric_limits<double>::infinity()) {
  return {.kind = Motion::Kind::Curvature, .speed = scale, .dt = kCurvatureDt, .substeps = 1, .curvatureLimit = limit};
}

// Ghost voxels a stencil reads beyond the evolved region (second-order ENO needs 2).
constexpr int kStencilReach = 2;

float minmod(float a, float b) {
  if (a * b <= 0) return 0;
  return std::fabs(a) < std::fabs(b) ? a : b;
}

double window1(double t) {
  if (t >= 1) return 0;
  const double u = 1 - t * t;
  return u * u;
}

// Godunov |grad phi| with second-order ENO one-sided differences, upwind for speed sign.
// Single precision: the field is stored in floats and the differences are of order 1.
float upwindGradient(const float* v, std::size_t i, const std::size_t stride[3], bool outward) {
  float g2 = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t s = stride[a];
    const float vm2 = v[i - 2 * s], vm1 = v[i - s], v0 = v[i], vp1 = v[i + s], vp2 = v[i + 2 * s];
    const float dm = (v0 - vm1) + 0.5f * minmod(v0 - 2 * vm1 + vm2, vp1 - 2 * v0 + vm1);
    const float dp = (vp1 - v0) - 0.5f * minmod(vp1 - 2 * v0 + vm1, vp2 - 2 * vp1 + v0);
    const float a1 = outward ? std::max(dm, 0.0f) : std::min(dm, 0.0f);
    const float a2 = outward ? std::min(dp, 0.0f) : std::max(dp, 0.0f);
    g2 += a1 * a1 + a2 * a2;
  }
  return std::sqrt(g2);
}

// Moves the band voxels of `region` (|phi| < band) by m. region must lie kStencilReach inside
// the grid. Work is split in fixed blocks, each voxel computed alone: thread-count independent.
void evolve(DenseGrid& g, const Box& region, float band, const Motion& m, ThreadPool& pool) {
  std::vector<std::uint32_t> list;
  std::vector<float> speed;
  const std::size_t stride[3] = {1, g.sx, g.sxy};
  for (int z = region.lo.z; z < region.hi.z; ++z)
    for (int y = region.lo.y; y < region.hi.y; ++y) {
      std::size_t i = g.index({region.lo.x, y, z});
      for (int x = region.lo.x; x < region.hi.x; ++x, ++i) {
        const float d = g.v[i];
        if (!(std::fabs(d) < band)) continue;
        double w = 1;
        if (m.windowed) {
          // Foot point by the central-difference gradient: the window is constant along normals.
          Vec3 n{0.5 * (g.v[i + 1] - g.v[i - 1]), 0.5 * (g.v[i + g.sx] - g.v[i - g.sx]),
                 0.5 * (g.v[i + g.sxy] - g.v[i - g.sxy])};
          n = normalized(n);
          const Vec3 q = Vec3{double(x), double(y), double(z)} - n * d;
          for (int a = 0; a < 3 && w > 0; ++a) w *= window1(std::fabs(q[a] - m.center[a]) / m.radius);
          if (w <= 0) continue;
        }
        list.push_back(std::uint32_t(i));
        speed.push_back(float(m.speed * w));
      }
    }
  if (list.empty()) return;
  std::vector<float> next(list.size());
  constexpr std::size_t kBlock = 4096;
  const std::size_t blocks = (list.size() + kBlock - 1) / kBlock;
  for (int step = 0; step < m.substeps; ++step) {
    const float* v = g.v.data();
    pool.parallelFor(blocks, [&](std::size_t b) {
      const std::size_t end = std::min(list.size(), (b + 1) * kBlock);
      for (std::size_t k = b * kBlock; k < end; ++k) {
        const std::size_t i = list[k];
        const double f = speed[k];
        if (m.kind == Motion::Kind::Advect) {
          next[k] = v[i] - float(m.dt * f) * upwindGradient(v, i, stride, f > 0);
        } else {
          double lap = v[i + 1] + v[i - 1] + v[i + g.sx] + v[i - g.sx] + v[i + g.sxy] + v[i - g.sxy] - 6.0 * v[i];
          lap = std::clamp(lap, -m.curvatureLimit, m.curvatureLimit);
          next[k] = float(v[i] + m.dt * f * lap);
        }
      }
    });
    for (std::size_t k = 0; k < list.size(); ++k) g.v[list[k]] = next[k];
  }
}

void checkBrush(const Volume& vol, const BrushParams& p) {
  if (!isFinite(p.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  requireRange(p.radius, 0.5, kMaxDomainSide, "radius");
  requireFinite(p.strength, "strength");
  if (!(p.strength > 0 && p.strength <= 1))
    throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  if (boxAround(p.center, {p.radius, p.radius, p.radius}).intersect(vol.domain()).empty())
    throw EngineError(ErrorKind::OutOfDomain, "center", "the tool's region lies outside the volume");
}

Edit applyBrush(Volume& vol, const BrushParams& p, Motion m, ThreadPool& pool) {
  checkBrush(vol, p);
  m.windowed = true;
  m.center = p.center;
  m.radius = p.radius;
  const float band = vol.band();
  const Box roi = boxAround(p.center, {p.radius, p.radius, p.radius}).intersect(vol.domain());
  // The surface moves only inside the ROI (W = 0 on its boundary, voxels outside are not
  // evolved), so the new zero set lies within one voxel of it: every voxel further than
  // band + 1 from the ROI keeps its distance, and every band voxel nearer may now be closer to
  // the moved surface than to the old one. That shell is reset and marched too, from the kept
  // voxels inside and outside the ROI; the old field beyond it is the source the march
  // continues from (its distances are still right there).
  const int reach = int(std::ceil(band)) + 1;
  const Box region = roi.grown(reach).intersect(vol.domain());
  // One more voxel for the kept-voxel test at the region's edge, and the stencils' reach
  // around the ROI.
  DenseGrid g = DenseGrid::gather(vol, roi.grown(std::max(reach + 1, kStencilReach)));
  evolve(g, roi, band, m, pool);
  RedistanceOptions options;
  options.normalizeOnly = roi;
  redistanceRegion(g, region, band, Outside::Source, options);
  Edit e;
  e.region = region;
  e.changes = vol.scatter(region, g.v.data(), g.box);
  return e;
}

// One global application: every chunk evolves its whole grid but a stencil-wide ghost ring,
// then redistances it. The margin covers the sub-steps' stencils, the kept voxels' neighbours
// and the band, so each chunk's interior comes out as if the volume were one grid.
Edit applyGlobal(Volume& vol, const Motion& m, ThreadPool& pool) {
  const float band = vol.band();
  const int margin = int(std::ceil(band)) + 2 + kStencilReach * (m.substeps + 1);
  Edit e;
  e.region = vol.domain();
  e.changes = chunkedPass(vol, margin, pool, [&](DenseGrid& g, const Box&, ThreadPool& inner) {
    const Box region = g.box.grown(-kStencilReach);
    evolve(g, region, band, m, inner);
    redistanceRegion(g, region, band, Outside::Ignored);
  });
  return e;
}

Edit morph(Volume& vol, double k, double sign, ThreadPool& pool) {
  const int steps = int(std::ceil(k - 1e-9));
  const Motion m = advection(sign * k / steps);
  Edit total;
  for (int s = 0; s < steps; ++s) {
    Edit e = applyGlobal(vol, m, pool);
    total.append(e.changes, e.region);
  }
  return total;
}

void checkMorphRadius(double k, const char* field) { requireRange(k, 1e-3, 64, field); }

}  // namespace

Edit addBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, p, advection(p.strength), pool);
}

Edit removeBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, p, advection(-p.strength), pool);
}

Edit smooth(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, p, curvatureFlow(p.strength), pool);
}

Edit sharpen(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, p, curvatureFlow(-p.strength, kSharpenCurvatureLimit), pool);
}

Edit meanCurvatureFlow(Volume& vol, int iterations, double strength, ThreadPool& pool) {
  requireRange(iterations, 1, 100000, "iterations");
  requireFinite(strength, "strength");
  if (!(strength > 0 && strength <= 1)) throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  const Motion m = curvatureFlow(strength);
  Edit total;
  for (int it = 0; it < iterations; ++it) {
    Edit e = applyGlobal(vol, m, pool);
    total.append(e.changes, e.region);
  }
  return total;
}

Edit dilate(Volume& vol, double k, ThreadPool& pool) {
  checkMorphRadius(k, "radius");
  return morph(vol, k, +1, pool);
}

Edit erode(Volume& vol, double k, ThreadPool& pool) {
  checkMorphRadius(k, "radius");
  return morph(vol, k, -1, pool);
}

Edit openSolid(Volume& vol, double r, ThreadPool& pool) {
  checkMorphRadius(r, "radius");
  Edit e = morph(vol, r, -1, pool);
  Edit d = morph(vol, r, +1, pool);
  e.append(d.changes, d.region);
  return e;
}

Edit closeSolid(Volume& vol, double r, ThreadPool& pool) {
  checkMorphRadius(r, "radius");
  Edit e = morph(vol, r, +1, pool);
  Edit d = morph(vol, r, -1, pool);
  e.append(d.changes, d.region);
  return e;
}

}  // namespace marzipan
