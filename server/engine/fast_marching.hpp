// Redistancing by the Fast Marching Method on a dense grid (docs/method.md §5).
//
// Each side of the surface is marched outward from its Source voxels: a voxel's distance is
// computed only from known voxels of its own sign (and the other side's sources, for the
// second-order stencil). The two sides are therefore independent, and run at once on two
// threads when the pool has them and the band is large enough to pay for waking one (8192
// candidates); the result does not depend on it. The priority queue is an
// exact bucket queue: buckets of 1/32 vu are taken in order, and a voxel lowered after it was
// taken is taken again, so the result is the same as that of a binary-heap marcher (up to
// float rounding) at a fraction of the cost. A voxel's first solve waits until the neighbours
// it uses are known (about one solve per voxel). The march works in place on the grid's values.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "dense_grid.hpp"
#include "progress.hpp"

namespace marzipan {

class ThreadPool;

enum class MarchState : std::uint8_t {
  Unknown = 0,   // to be computed; only the sign of its value is read
  Source = 5,    // value is a known signed distance and is kept
  Ignored = 12,  // neither read nor written (e.g. a stale ghost layer)
};

enum class MarchOrder {
  First,   // first-order upwind differences
  // Sethian's second-order differences where two upwind voxels are known and the run is
  // clearly monotone (a - b >= 0.2 vu). Across a kink, where the two voxels straddle the
  // closest point (b ~ a), the one-sided extrapolation would invent a slope that is not there.
  Second,
};

struct MarchStats {
  std::size_t accepted = 0;   // voxels taken from the queue, retakes included
  std::size_t retaken = 0;    // voxels lowered after they were taken
  std::size_t solved = 0;     // eikonal solves (each voxel is solved about once per side it is marched on)
};

// The band a march accepts (vu); anything else, NaN included, throws EngineError
// (InvalidArgument, field "band"). It sizes the bucket queue, and a distance's bucket and
// solve-table index are converted through 32 bits, which holds for distances below it.
constexpr double kMinMarchBand = 0.5, kMaxMarchBand = 1024;

// grid: signed values; state: one MarchState per voxel of grid (same index).
// On return every Unknown voxel holds sign * min(distance to its side's sources, band).
MarchStats fastMarch(DenseGrid& grid, const std::vector<MarchState>& state, float band,
                     MarchOrder order = MarchOrder::Second);

// The marcher's own per-voxel classification, for callers that classify a region themselves
// (redistance.cpp) instead of filling a MarchState per voxel of the grid. The low bits are
// MarchState's values.
namespace march_flag {
inline constexpr std::uint8_t kKnown = 1;     // a source: its value is kept and may be used
inline constexpr std::uint8_t kNeg = 2;       // inside (value < 0)
inline constexpr std::uint8_t kFrozen = 4;    // source or ignored: never recomputed
inline constexpr std::uint8_t kIgnored = 8;
inline constexpr std::uint8_t kInterior = 16; // at least 2 voxels from every face of the grid
// Free for the caller's own bookkeeping; the marcher does not read them.
inline constexpr std::uint8_t kCallerA = 32;
inline constexpr std::uint8_t kCallerB = 64;
// An unknown voxel whose value is already an upper bound of its distance (the distance to a
// part of the surface that did not move): its side reads it from the start, and the march
// lowers it only where the rest of the surface comes nearer. It is no source of the other side.
inline constexpr std::uint8_t kUpperBound = 128;
}  // namespace march_flag

// The march proper. flags: one march_flag byte per grid voxel. Every unknown voxel (no
// kFrozen) must already hold +-band with its side's sign, or a smaller upper bound marked
// kUpperBound. candidates: every source or upper bound of the grid with |value| < band that may
// border an unknown voxel of its side, in increasing index order (a superset is fine). Writes
// only unknown voxels. progress: checked every few buckets
// of each side (throws Cancelled, leaving the grid part-marched) and advanced in step with the
// buckets taken.
// Frees the calling thread's march scratch (kept from one march to the next) when it was sized
// for a grid of more than `voxels` voxels: a huge tool's arrays are not worth keeping.
void trimMarchScratch(std::size_t voxels);
// The bytes of the calling thread's march scratch arrays that grow with the grid (for tests).
std::size_t marchScratchBytes();

// parallelSides: the two sides on two threads of the pool (when it has them) whatever the
// candidates' count (RedistanceOptions::parallelSides); the same result either way.
MarchStats fastMarchClassified(DenseGrid& grid, const std::vector<std::uint8_t>& flags,
                               std::span<const std::uint32_t> candidates, float band, MarchOrder order,
                               ThreadPool& pool, ProgressShare progress = {}, bool parallelSides = false);

}  // namespace marzipan
