// Helpers shared by the engine tests: analytic answers to compare against, a guard for the
// tests that limit the kernels' vector width, and the report of a test that cannot run here.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <vector>
#include <numbers>
#include <string_view>

#include "engine/measures.hpp"
#include "engine/simd_width.hpp"
#include "engine/volume.hpp"

namespace marzipan::test {

// Puts the kernels back to their widest form when it goes out of scope: a test that limits the
// width (simd_width::limitWidth) leaves the next one as it found it, also when it fails.
struct WidestWidthAtExit {
  WidestWidthAtExit() = default;
  WidestWidthAtExit(const WidestWidthAtExit&) = delete;
  WidestWidthAtExit& operator=(const WidestWidthAtExit&) = delete;
  ~WidestWidthAtExit() { simd_width::limitWidth(simd_width::Width::Widest); }
};

// Reports the running test as skipped; the caller returns right after. Catch2 v2 has no skip,
// and a test that returns without checking anything passes: tests/CMakeLists.txt has ctest
// report an entry whose output holds this marker as skipped (SKIP_REGULAR_EXPRESSION) instead.
inline constexpr std::string_view kSkippedMarker = "MARZIPAN-SKIPPED:";
inline void reportSkipped(std::string_view why) { std::cout << kSkippedMarker << ' ' << why << std::endl; }

// Whether the kernels have AVX2 forms that this CPU runs; reports the test skipped when not (a
// comparison of the widths would compare SSE2 with itself).
inline bool avx2OrSkipped() {
  if (simd_width::avx2Available()) return true;
  reportSkipped("this CPU (or build) has no AVX2: both widths would run the SSE2 kernels");
  return false;
}

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

// Band voxels with no surface near them: |d| < 0.9 band but no voxel of the other sign within
// |d| + 1.5 vu. A true distance field has none; spurious voxels (Bærentzen 2002, Fig. 7.11; docs/method.md) do.
inline int strayBandVoxels(const Volume& v) {
  int stray = 0;
  const Int3 n = v.dims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const float d = v.at(x, y, z);
        if (!(std::fabs(d) < 0.9f * v.band())) continue;
        const int r = int(std::ceil(std::fabs(d) + 1.5));
        bool found = false;
        for (int k = -r; k <= r && !found; ++k)
          for (int j = -r; j <= r && !found; ++j)
            for (int i = -r; i <= r && !found; ++i) found = (v.at(x + i, y + j, z + k) < 0) != (d < 0);
        stray += found ? 0 : 1;
      }
  return stray;
}

// Gives every stored brick of vol the channels texelAt(brick, local index) and publishes them:
// channels without the paint tool, for the tests of storage, digest and file. Returns the changes.
template <class TexelAt>
std::vector<BrickChange> paintBricks(Volume& vol, TexelAt texelAt) {
  std::vector<BrickChange> changes;
  vol.forEachPresentBrick([&](Int3 b, const Brick&) {
    auto bp = std::make_shared<BrickPaint>();
    for (int i = 0; i < kBrickVoxels; ++i) bp->t[i] = texelAt(b, i);
    BrickRef old = vol.brick(b);
    BrickRef now = old;
    now.paint = vol.canonicalPaint(std::move(bp));
    if (!(now == old)) changes.push_back({b, std::move(old), std::move(now)});
  });
  vol.publish(changes, true);
  return changes;
}

// Every voxel's distance as bits, and every voxel's texel, over the whole domain: what the
// bit-for-bit checks compare.
inline std::vector<std::uint32_t> distanceBits(const Volume& v) {
  std::vector<float> d(std::size_t(v.domain().voxels()));
  v.gather(v.domain(), d.data());
  std::vector<std::uint32_t> bits(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) bits[i] = std::bit_cast<std::uint32_t>(d[i]);
  return bits;
}

inline std::vector<Texel> allTexels(const Volume& v) {
  std::vector<Texel> t(std::size_t(v.domain().voxels()));
  v.gatherTexels(v.domain(), t.data());
  return t;
}

// How many entries of two arrays of the same length differ (Catch would print every one).
template <class T>
std::size_t differing(const std::vector<T>& a, const std::vector<T>& b) {
  std::size_t n = a.size() == b.size() ? 0 : std::max(a.size(), b.size());
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) n += !(a[i] == b[i]);
  return n;
}

}  // namespace marzipan::test
