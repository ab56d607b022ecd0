// The redistance's flags pass (redistance.cpp, redistanceRegion): the march_flag byte of every
// voxel of a tool's grid before its band list is classified, from the reset and marked boxes and
// the sign of each value, a z-slab at a time. Internal to the engine. The pass visits ten to
// twenty times more voxels than the band, so it works 16 voxels a step with SSE2 and 32 with AVX2
// (simd_width.hpp), each giving exactly what its scalar loop gives.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "dense_grid.hpp"
#include "fast_marching.hpp"
#include "geometry.hpp"
#include "progress.hpp"

namespace marzipan::redistance_flags {

// The caller's bits of the march's flags (march_flag::kCallerA and kCallerB).
inline constexpr std::uint8_t kReset = march_flag::kCallerA;   // in the region and to be reset unless kept
inline constexpr std::uint8_t kMarked = march_flag::kCallerB;  // in a box where kept voxels are normalized

// One piece (z-slab) of the flags pass: for the current z-slice, how many reset and how many
// marked boxes hold each voxel position of it (x fastest), kept as the slices go up (a box adds
// its rectangle where it begins and takes it away where it ends), and the interior bit of an
// inner slice's positions; from those the two bytes of each position (flags = pos, or pos ^ flip
// where the value is negative), in the rows of the boxes that began or ended there, then each
// slice's flags 16 voxels at a time. (Rebuilt slice by slice from the boxes' merged runs, the
// pass cost a stroke's slanted line of boxes 0.49M instructions a message, 6% of it: the boxes
// holding a slice changed at almost every slice, and the runs at almost every row. Now 0.23M.)
struct FlagPiece {
  std::vector<std::uint16_t> resetCount, markedCount;
  std::vector<std::uint8_t> interior;
  std::vector<std::uint8_t> pos, flip;  // the slice's two bytes per position (signFlags), as the counts leave them
};

// What the flags pass writes before the band list is classified, by position: outside the
// reset boxes a source (or ignored); inside them reset, or a source on the side that is already
// exact; kMarked inside the marked boxes; kInterior 2 voxels from every face; kNeg by sign.
struct FlagLayout {
  std::span<const Box> reset, marked;  // clipped to the region (so inside the grid), sorted by lo.x
  std::uint8_t base;                   // outside the reset boxes
  int exactSide;
};

// The flags of z-slices [z0, z1) of g. Each voxel's byte depends only on its position and the
// sign of its value, so any split into slabs gives the same bytes.
void flagSlices(const DenseGrid& g, std::uint8_t* flags, const FlagLayout& layout, int z0, int z1, FlagPiece& fp,
                const ProgressShare& progress);

}  // namespace marzipan::redistance_flags
