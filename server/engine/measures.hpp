// Measures of a solid, for tests, the command line and the service. Sign and units as in
// volume.hpp; all are read-only and safe on a copy held by another thread.
#pragma once

#include <cstdint>
#include <string>

#include "geometry.hpp"
#include "volume.hpp"

namespace marzipan {

// Inside volume in vu^3: each voxel counts clamp(0.5 - d, 0, 1), exact for a plane.
double insideVolume(const Volume& vol);

// Surface area in vu^2: sum of delta_eps(d) |grad d| with a raised-cosine delta of half
// width 1.5 vu (relative error about 0.3/R^2 on a sphere of radius R).
double surfaceArea(const Volume& vol);

// Number of 6-connected components of inside voxels (d < 0).
int countComponents(const Volume& vol);

struct Bounds {
  bool empty = true;
  Vec3 lo, hi;  // of the zero set, by linear interpolation along grid edges, in vu
};
Bounds boundingBox(const Volume& vol);

// | |grad d| - 1 | by central differences at voxels adjacent to the surface (a 6-neighbour of
// the other sign): the distance-field error of Bærentzen 2002, section 7.6.0.4 (docs/method.md).
struct GradientError {
  double max = 0, mean = 0;
  std::size_t voxels = 0;
};
GradientError gradientError(const Volume& vol);
// The same over the voxels of `region` only.
GradientError gradientError(const Volume& vol, const Box& region);

// A 64-bit hash of the field (dims, band and every brick's values): identical volumes have
// identical digests whatever their history. It is a sum (mod 2^64) of one term per brick, so a
// session can follow it through edits by swapping the terms of the changed bricks instead of
// reading the whole volume: digest = digestFromTerms(dims, band, sum of brickDigestTerm, base).
// The channels (channels.hpp) count once painted: a brick's BrickPaint is hashed into its term,
// and a base colour other than kClayColor into the whole; a volume never painted, of the clay
// colour, has the digest it had before volumes had channels (journals and pinned digests hold).
std::uint64_t digest(const Volume& vol);
std::string digestHex(const Volume& vol);
// A brick's term: 0 for uniform outside (what an absent brick is), a hash of its position and
// kind for uniform inside, and of its position and every value (then every texel, when it has
// channels) for a brick with data.
std::uint64_t brickDigestTerm(Int3 brick, const BrickRef& ref);
std::uint64_t digestFromTerms(Int3 dims, float band, std::uint64_t termSum, Rgb8 base = kClayColor);
std::uint64_t digestTermSum(const Volume& vol);
std::string digestText(std::uint64_t digest);  // 16 lower-case hex digits

struct Measures {
  double insideVolume = 0, surfaceArea = 0;
  int components = 0;
  Bounds bounds;
  GradientError gradientError;
  std::string digest;
};
Measures measure(const Volume& vol);

}  // namespace marzipan
