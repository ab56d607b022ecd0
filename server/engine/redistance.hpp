// Redistancing after an edit (docs/method.md §3, §5): keep the voxels adjacent to the
// zero set, reset every other voxel of the edited region, and march distances out from the
// kept ones. Resetting everything is what keeps vanished parts from leaving stray voxels.
#pragma once

#include <span>

#include "dense_grid.hpp"
#include "fast_marching.hpp"
#include "thread_pool.hpp"

namespace marzipan {

class Volume;

enum class Outside {
  Source,   // voxels of the grid outside the region are valid distances (a local tool)
  Ignored,  // they are a stale ghost layer (one chunk of a global operation)
};

// The voxels of a box of a grid whose value is not exactly +-band, in index order, with their
// positions (volume coordinates). Every other voxel of the box lies at least band from the
// surface: the work of a tool grows with this list (the band), not with its box.
struct BandVoxels {
  Box box;
  std::vector<std::uint32_t> index;
  std::vector<Int3> point;

  // progress: checked per z-slice, advanced by its whole share at the end.
  void collect(const DenseGrid& grid, const Box& box, float band, const ProgressShare& progress = {});
  // The band voxels of box that lie in one of `parts` (boxes; clipped to box), in index order,
  // and those between two parts holding the same row: a slanted stroke's box is mostly far from
  // its ROIs, whose union holds all the band its tool can move or reset, and along a stroke the
  // parts holding a row overlap. One part that covers the box (a dab's) lists what collect
  // above lists. `box` is still b clipped to the grid.
  void collect(const DenseGrid& grid, const Box& box, std::span<const Box> parts, float band,
               const ProgressShare& progress = {});
  // The same list, when the grid holds vol's values as gathered (DenseGrid::gatherFrom): the
  // bricks vol does not store read exactly +-band there, so only the stored ones are scanned.
  // A whole-volume pass's chunk is mostly such bricks.
  void collect(const DenseGrid& grid, const Box& box, float band, const Volume& vol);
};

// How to treat the voxels of the region before marching.
struct RedistanceOptions {
  // Each kept value d is first replaced by d / |grad d| (central differences), bounded by the
  // crossing on its edges: the zero set stays where it is, and the slope errors that tools
  // leave in kept voxels do not accumulate. Without it, the mean curvature flow of a sphere
  // runs 1.5% fast after a few hundred applications (R^2 = R0^2 - 4.06 t instead of 4 t).
  bool normalizeKept = true;
  // When not empty: only the region's voxels inside one of these boxes are reset; the others
  // are sources like those outside it. A local tool resets the band around its ROIs.
  std::span<const Box> resetBoxes;
  // When not empty: only kept voxels inside one of these boxes are normalized. A local tool
  // normalizes only where it moved the surface, so that the zero set around it stays exactly
  // where it was.
  std::span<const Box> normalizeBoxes;
  // When not empty (a local tool): the boxes of voxels the caller changed; the surface moved
  // only through the cells touching them. A far voxel (not adjacent to the zero set) of the
  // reset boxes outside them was a distance to the old surface. When no such cell is nearer
  // than its value, that is still its distance, and it is kept as a source. Otherwise, when its
  // foot point lies well away from those cells, its nearest surface did not move: its value is
  // an upper bound, which the march lowers only where the moved surface comes nearer. Only the
  // others are reset. The march then works on the band the moved surface affects, not the
  // whole of the reset boxes. Kept voxels are then normalized only inside these boxes
  // (normalizeBoxes is not read).
  std::span<const Box> movedBoxes;
  // +1 / -1: the values on the outside / inside are already exact distances (a union's
  // outside, an intersection's inside) and are kept; only the other side is marched.
  int exactSide = 0;
  // The surface moved by at most kMaxDirectMotion vu since the region was a distance field, at
  // a speed extended along the normals, so that the level sets near it moved with it (an
  // advection: a brush's application, a sub-step of a stroke's height, one step of dilation or
  // erosion). A far voxel to reset within 1.75 vu of the surface, whose neighbours all lie
  // well inside the band and whose gradient is within 0.1 of unit length, then takes
  // d / |grad d| (central differences) as a kept voxel does, and is a source of the march like
  // them: the march covers only the rest of the band. Where the gradient is no unit vector (a
  // kink: surfaces meeting or parting) the voxel is marched. docs/method.md §5.
  bool direct = false;
  MarchOrder order = MarchOrder::Second;
  // The march's two sides on two threads of the pool whatever the band's size (else only from
  // fastMarchClassified's kParallelCandidates on): for a caller whose passes just ran on the
  // pool, whose threads still look for work (ThreadPool::kSpin) and take the second side at
  // once. A small tool's passes run on the calling thread, and waking a sleeping pool thread
  // for its march cost about what the march saved.
  bool parallelSides = false;
  // When set: the band voxels of region grown by 1 (clipped to the grid), as collected
  // before the caller changed some of them (it may only have changed voxels of the list).
  // Saves the scan of the box. It may leave out voxels that lie outside every reset box grown
  // by 1 (BandVoxels::collect with parts): those are neither reset nor next to a reset voxel,
  // so the classification and the march's seeds pass them over anyway.
  const BandVoxels* band = nullptr;
  // The caller's progress (progress.hpp): checked throughout (a cancelled call throws
  // Cancelled and leaves the grid part-redistanced), advanced by its share as the call goes.
  ProgressShare progress;
};

// The largest motion of the surface (vu) for which RedistanceOptions::direct holds.
constexpr double kMaxDirectMotion = 1.0;

// Redistances `region` (clipped to grid.box) of the grid in place. A voxel is adjacent to
// the zero set when it is 0 or one of its 6 neighbours has the other sign (0 counts as outside).
// The two sides of the surface are marched on two threads, and the classification before the
// march is split into fixed pieces on the pool, when the pool has threads and the grid is large
// enough to pay for waking them, the sides also when options.parallelSides asks (the same
// result either way).
MarchStats redistanceRegion(DenseGrid& grid, const Box& region, float band, Outside outside,
                            const RedistanceOptions& options = {}, ThreadPool& pool = ThreadPool::serial());

// Frees the calling thread's scratch of redistanceRegion and of the march (kept from one call
// to the next: a dab's arrays are reused thousands of times) when it was sized for a grid of
// more than `voxels` voxels. A huge tool's would otherwise stay for the thread's lifetime
// (about 3 bytes per voxel of its grid: flags and each side's state).
void trimRedistanceScratch(std::size_t voxels);
// The bytes of those arrays that grow with the grid, the march's included (for tests).
std::size_t redistanceScratchBytes();

// Turns an approximate signed distance (right sign, right zero set, |grad| not 1) into a
// true distance field over the whole volume: kept voxels are scaled by 1/|grad| first.
// Used for solids built from CSG and smooth blends.
void redistanceVolume(Volume& vol, ThreadPool& pool);

}  // namespace marzipan
