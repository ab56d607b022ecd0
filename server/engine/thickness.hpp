// Wall thickness for printing: how thick the solid is under each surface point, measured from
// the distance field.
//
// Conventions: vu; d < 0 inside, the normal n points outward. The thickness at a surface point
// p is the length of the chord from p along -n to where the ray leaves the solid (the first
// zero of the trilinear interpolant going from inside to outside). For a slab of thickness T
// that is T, for a spherical shell R1 - R2, for a cylinder of radius r seen from its side 2r.
#pragma once

#include <cstddef>
#include <vector>

#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

// The chord length from the surface point p along -n (n unit, outward), from where the line
// through p meets the zero set within 1 vu of p (p itself if it does not); the ray is marched by
// the distance field (steps of max(|d|, 0.25 vu), d being at least that far from the surface
// where it is a distance, and clamped to the band beyond it), and the exit refined by
// bisection to 1e-3 vu. Voxels outside the domain read +band, so every ray ends.
double thicknessAt(const Volume& vol, Vec3 p, Vec3 n);

struct ThinPlace {
  Vec3 point;       // on the surface, vu
  Vec3 normal;      // outward unit normal there
  double thickness;  // vu
};

struct ThicknessReport {
  std::size_t points = 0;  // surface points measured (marching-cubes vertices)
  std::size_t below = 0;   // of those, thinner than min
  double thinnest = 0;     // the smallest thickness measured (0 for an empty solid)
  // The thinnest places, thinnest first, at most maxPlaces, each at least `spacing` vu from
  // those before it (one entry per thin region rather than its every vertex). Only points
  // thinner than min are listed.
  std::vector<ThinPlace> places;
};

// Measures every vertex of the surface's marching-cubes mesh, with its normal. Throws
// EngineError(InvalidArgument) unless min > 0 and finite. Identical for any thread count.
ThicknessReport analyzeThickness(const Volume& vol, double min, std::size_t maxPlaces = 64, double spacing = 4,
                                 ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
