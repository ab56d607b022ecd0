// Helpers shared by the engine tests: analytic answers to compare against.
#pragma once

#include <cmath>
#include <numbers>

#include "engine/measures.hpp"
#include "engine/volume.hpp"

namespace marzipan::test {

// Radius of the sphere with the solid's inside volume.
inline double equivalentRadius(const Volume& v) {
  return std::cbrt(3.0 * insideVolume(v) / (4.0 * std::numbers::pi));
}

// Largest |d - exact| over the voxels of `box` where the exact distance is within `within`.
template <class F>
double maxErrorNear(const Volume& v, const Box& box, double within, F exact) {
  double worst = 0;
  for (int z = box.lo.z; z < box.hi.z; ++z)
    for (int y = box.lo.y; y < box.hi.y; ++y)
      for (int x = box.lo.x; x < box.hi.x; ++x) {
        const double e = exact(Vec3{double(x), double(y), double(z)});
        if (std::fabs(e) < within) worst = std::max(worst, std::fabs(v.at(x, y, z) - e));
      }
  return worst;
}

}  // namespace marzipan::test
