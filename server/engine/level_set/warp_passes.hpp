// What the passes of one warp share: applyWarp (warp.cpp) gathers the base around the field's
// support, builds the inverse map (warp_lattice.hpp), resamples the voxels the flow moves
// (warp_resample.cpp), gives the kept voxels next to the zero set their distances
// (warp_feet.cpp), redistances and writes back. Grid indices and strides are the scratch
// grids' (x fastest; base and warped share one box), points are volume coordinates, and each
// pass runs on the pool a slice, or a layer of the lattice's cells, per task.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "engine/dense_grid.hpp"
#include "engine/level_set/warp_fields.hpp"
#include "engine/level_set/warp_lattice.hpp"
#include "engine/level_set/warp_reads.hpp"
#include "engine/progress.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"

namespace marzipan::level_set::warp {

// A voxel (of index k) that the resample read through the inverse map integrated at it: X(x),
// phi1 there and the map's Jacobian, I + segAxis along^T (a snake hook's capsule,
// Velocity::capsuleInverse(); WarpPass::exactSlopes). The kept-voxel pass (warp_feet.cpp)
// takes the slope of such a voxel next to the zero set from these instead of integrating the
// map again.
struct ExactRead {
  std::size_t k;
  double phi;
  Vec3 q, along;
  // The resample fills in the rest (not zeroed first).
  explicit ExactRead(std::size_t index) : k(index) {}
};

struct WarpScratch {
  DenseGrid base, warped;
  InverseLattice lattice;
  // The channels of base over the grids' box, and the warped ones (painted volumes only).
  std::vector<Texel> texels, warpedTexels;
  // The resample's ExactReads per slice of the work box, in index order (WarpPass::exactSlopes).
  std::vector<std::vector<ExactRead>> exactReads;
};

inline Box unite(const Box& a, const Box& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  Box u;
  for (int i = 0; i < 3; ++i) {
    u.lo[i] = std::min(a.lo[i], b.lo[i]);
    u.hi[i] = std::max(a.hi[i], b.hi[i]);
  }
  return u;
}

// The |value| read through the lattice below which the resample reads a voxel again through the
// flow integrated at it (warp_resample.cpp): kExactNear, or less where the lattice's error is
// known to be smaller.
float exactNear(const Velocity& v, bool painted);

// Whether the resample settles a lattice cell whose reads are all one block value of the base
// at once (InverseLattice::findBlocks, cellValue): not on a painted volume (the channels want
// each voxel's preimage), and not for a small snake hook (warp_resample.cpp).
bool readsCells(const Velocity& v, bool painted);

// One warp's field, grids and reads of the base, as its passes see them.
struct WarpPass {
  const Velocity& v;
  WarpScratch& s;
  Box work;  // the support within the domain
  float band;
  int steps;  // v.substeps()
  GridReads reads;  // of s.base
  // The resample's reads, and the kept voxels' (but the foot points'), lie within the
  // support grown by two voxels: its points' preimages stay in it (v vanishes on its boundary),
  // the lattice's nodes reach a voxel past it, and the slopes read half a voxel to each side.
  // When the grid holds that with a voxel to spare (a support within the domain: the margin is
  // wider), they are read without trilinear()'s tests.
  bool inGrid;
  // The resample reads a voxel whose value through the lattice is below this again through the
  // flow integrated at it (exactNear()); where it is below kExactNear, the kept-voxel pass reads
  // the others next to the zero set so itself.
  float exactNear;
  // Whether the resample settles the lattice's cells of one value at once (readsCells()).
  bool cells;
  // Whether the resample integrates the map's Jacobian with X where it reads through the flow,
  // and keeps them (WarpScratch::exactReads): where the kept-voxel pass reads the others next to
  // the zero set itself (exactNear below kExactNear, a snake hook's capsule), almost every voxel
  // it reads so is next to the zero set and wants its slope there. Never on a painted volume
  // (exactNear() is kExactNear there).
  bool exactSlopes;

  WarpPass(const Velocity& field, WarpScratch& scratch, const Box& within, float bandValue, bool painted)
      : v(field), s(scratch), work(within), band(bandValue), steps(field.substeps()), reads(scratch.base),
        inGrid(field.support().grown(3).intersect(scratch.base.box) == field.support().grown(3)),
        exactNear(warp::exactNear(field, painted)), cells(readsCells(field, painted)),
        exactSlopes(exactNear < kExactNear && field.kind == Velocity::Kind::Capsule) {}

  [[gnu::always_inline]] double read(Vec3 at) const {
    return inGrid ? trilinear<true>(reads, at, band) : trilinear(reads, at, band);
  }
  // Next to the zero set, where the surface's place is read, the cubic interpolant (tricubic()):
  // the value trilinear() gives there lies h^2 kappa / 8 above a convex distance. Inlined into
  // the resample's loop: a call of its own cost a snake hook move 0.25% more instructions.
  [[gnu::always_inline]] double readNear(Vec3 at) const {
    double out;
    return tricubic(reads, at, out) ? out : read(at);
  }
  // The same where the point may lie anywhere (the foot points).
  double readNearAnywhere(Vec3 at) const {
    double out;
    return tricubic(reads, at, out) ? out : trilinear(reads, at, band);
  }
};

// Each row's run of voxels that the flow moves, [x0, x1) per (y, z) of the work box: the
// resample finds them, the kept-voxel pass looks only within them.
struct Runs {
  Box work;
  std::vector<std::pair<int, int>> runs;
  explicit Runs(const Box& within)
      : work(within), runs(std::size_t(std::max(0, within.size().y)) * std::size_t(std::max(0, within.size().z))) {}
  std::pair<int, int>& at(int y, int z) {
    return runs[std::size_t(y - work.lo.y) + std::size_t(work.size().y) * std::size_t(z - work.lo.z)];
  }
  const std::pair<int, int>& at(int y, int z) const {
    return runs[std::size_t(y - work.lo.y) + std::size_t(work.size().y) * std::size_t(z - work.lo.z)];
  }
};

// A grab's field: a capsule without a plateau (its kept voxels all take foot points, and its
// tip is looked at after the redistance).
inline bool isGrab(const Velocity& v) { return v.kind == Velocity::Kind::Capsule && v.plateau == 0; }

// The resample (warp_resample.cpp): s.warped takes, at each voxel the flow moves, the base
// read at its preimage (and s.warpedTexels its colour, painted volumes only); `changed` and
// `recoloured` (one per slice of the work box) the boxes of the voxels whose distance, and
// whose channels, changed.
void resample(const WarpPass& w, const Volume& base, bool painted, bool masked, Runs& runs, std::vector<Box>& changed,
              std::vector<Box>& recoloured, ThreadPool& pool, const ProgressShare& progress);

// The kept voxels (warp_feet.cpp): within `moved` (the changed voxels' box, grown here by a
// voxel within the work box), the resampled voxels next to the zero set and their distances,
// per slice of `moved`, as (index, value) pairs; the calling thread's scratch, valid until its
// next call.
using KeptVoxels = std::vector<std::vector<std::pair<std::size_t, float>>>;
const KeptVoxels& keptVoxels(const WarpPass& w, Box& moved, const Runs& runs, ThreadPool& pool, const ProgressShare& progress);

// A grab's tip after the redistance of `within` (warp_feet.cpp): the voxels a layer in from
// the kept ones there take their distances to the kept ones' foot points.
void grabTipFeet(const WarpPass& w, const Box& within);

// vol becomes base warped by the flow of v (../level_set.hpp, warps).
Edit applyWarp(Volume& vol, const Volume& base, const Velocity& v, ThreadPool& pool);

}  // namespace marzipan::level_set::warp
