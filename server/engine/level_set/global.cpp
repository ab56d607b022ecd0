// The whole-volume motions: mean curvature flow, Euclidean morphology (dilate, erode, open,
// close) and the tests' advection in sub-steps, with W = 1 everywhere. One application is one
// chunked pass (chunked_pass.hpp): each chunk's grid is evolved but for a ghost ring and
// redistanced, its interior coming out as if the volume were one grid, the same for any thread
// count. Morphology by k runs in applications of at most 1 vu. Progress: one unit per pass.
#include <cmath>

#include "engine/chunked_pass.hpp"
#include "engine/errors.hpp"
#include "engine/level_set/internal.hpp"
#include "engine/redistance.hpp"

namespace marzipan {

using level_set::advection;
using level_set::curvatureFlow;
using level_set::evolve;
using level_set::kAdvectDt;
using level_set::kStencilReach;
using level_set::Motion;
using level_set::toolScratch;

namespace {

// One global application: every chunk evolves its whole grid but a stencil-wide ghost ring,
// then redistances it. The margin covers the sub-steps' stencils, the kept voxels' neighbours
// and the band, so each chunk's interior comes out as if the volume were one grid.
Edit applyGlobal(Volume& vol, const Motion& m, ThreadPool& pool) {
  const float band = vol.band();
  const int margin = int(std::ceil(band)) + 2 + kStencilReach * (m.substeps + 1);
  Edit e;
  e.region = vol.domain();
  const Volume& source = vol;  // read by the chunks, unchanged until the pass publishes
  e.changes = chunkedPass(vol, margin, pool, [&](DenseGrid& g, const Box&, ThreadPool& inner) {
    const Box region = g.box.grown(-kStencilReach);
    level_set::gatherMask(source, g);
    BandVoxels& voxels = toolScratch().band;
    voxels.collect(g, region.grown(1), band, source);
    evolve(g, region, band, m, nullptr, voxels, inner);
    RedistanceOptions options;
    options.band = &voxels;
    options.direct = level_set::movesBandTogether(m);
    redistanceRegion(g, region, band, Outside::Ignored, options, inner);
  });
  // Every voxel was redistanced but those the mask held (channels.hpp): no drift is left
  // (Volume::brickDrift) unless something is painted.
  if (vol.paintedBricks() == 0) vol.clearBrickDrift();
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

Edit advectInSubsteps(Volume& vol, double distance, int substeps, ThreadPool& pool) {
  requireRange(substeps, 1, 64, "substeps");
  requireFinite(distance, "distance");
  if (!(distance != 0 && std::fabs(distance) / substeps <= kAdvectDt))
    throw EngineError(ErrorKind::InvalidArgument, "distance", "must be nonzero and at most 0.5 vu per sub-step");
  Motion m = advection(distance / (kAdvectDt * substeps));
  m.substeps = substeps;
  return applyGlobal(vol, m, pool);
}

}  // namespace marzipan
