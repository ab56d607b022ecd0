// What the stroke tests share (test_stroke.cpp, test_tools.cpp): a slab to stroke along, a
// line of dabs on it, a stroke sent in messages, and the surface found by bisection of the
// interpolant (sign and units as in volume.hpp).
#pragma once

#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/solids.hpp"

namespace marzipan::test_strokes {

// A slab whose top face is y = 16, long in x.
inline Volume strokeSlab() { return makeBox({80, 40, 40}, {39.5, 12, 19.5}, {36, 4, 16}); }

// Dabs along the slab's top from x0 to x1 at z = 19.5, `spacing` apart, with the top's normal.
inline std::vector<StrokeDab> strokeLine(double x0, double x1, double spacing) {
  std::vector<StrokeDab> dabs;
  const int n = int(std::round((x1 - x0) / spacing));
  for (int i = 0; i <= n; ++i) dabs.push_back({{x0 + (x1 - x0) * i / n, 16, 19.5}, 1.0, {0, 1, 0}});
  return dabs;
}

// Sends the dabs as `messages` consecutive applications of one stroke that remembers them.
inline void sendStroke(Volume& v, const StrokeSettings& st, const std::vector<StrokeDab>& dabs, std::size_t messages,
                       bool accumulate = false) {
  std::vector<StrokeDab> memory;
  for (std::size_t m = 0; m < messages; ++m) {
    const std::size_t lo = dabs.size() * m / messages, hi = dabs.size() * (m + 1) / messages;
    const std::span<const StrokeDab> part(dabs.data() + lo, hi - lo);
    applyStroke(v, st, part, memory);
    if (!accumulate) memory.insert(memory.end(), part.begin(), part.end());
  }
}

// Height of the surface above y = 16 at (x, z = 19.5), by bisection of the interpolant.
inline double ridgeHeight(const Volume& v, double x) {
  double lo = 10, hi = 30;  // inside, outside
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (lo + hi);
    (v.sample({x, mid, 19.5}) < 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi) - 16;
}

// Distance from `centre` along `dir` (unit) to the surface, by bisection of the interpolant
// between `inside` and `outside` vu.
inline double surfaceAlong(const Volume& v, Vec3 centre, Vec3 dir, double inside, double outside) {
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (inside + outside);
    (v.sample(centre + dir * mid) < 0 ? inside : outside) = mid;
  }
  return 0.5 * (inside + outside);
}

}  // namespace marzipan::test_strokes
