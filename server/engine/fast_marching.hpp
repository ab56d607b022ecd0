// Redistancing by the Fast Marching Method on a dense grid (docs/method.md §5).
//
// Each side of the surface is marched outward from its Source voxels: a voxel's distance is
// computed only from known voxels of its own sign. The priority queue is an exact bucket
// queue: buckets of 1/32 vu are taken in order, and a voxel lowered after it was taken is
// taken again, so the result is the same as that of a binary-heap marcher (up to float
// rounding) at a fraction of the cost.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "dense_grid.hpp"

namespace marzipan {

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
};

// grid: signed values; state: one MarchState per voxel of grid (same index).
// On return every Unknown voxel holds sign * min(distance to its side's sources, band).
MarchStats fastMarch(DenseGrid& grid, const std::vector<MarchState>& state, float band,
                     MarchOrder order = MarchOrder::Second);

}  // namespace marzipan
