// The stepping kernels: one explicit sub-step of the band's motion over the runs of listed
// voxels (internal.hpp: Run, MovedVoxels), upwind advection (Godunov, second-order ENO) or a
// curvature step (the 7-point Laplacian). Each has a scalar definition and SSE2 (four voxels
// at once) and AVX2 (eight) forms that do the definition's float and double operations in its
// order in every lane, so every width gives the same bits (simd_width.hpp picks one at run
// time; no FMA anywhere, -ffp-contract=off). On x86-64 the definitions, in the #else of the
// SSE2 forms, are compiled only with MARZIPAN_SCALAR_KERNELS, into engine_scalar_tests
// (tests/CMakeLists.txt), which must give the pinned fields of
// tests/engine/level_set/test_kernels.cpp. A new motion's kernel goes here, in its three forms.
//
// A header, included by the driver (moving.cpp) alone: its loops call a kernel per z-slice and
// sub-step, and out of line the call's setup (the width's test, the lanes' constants) cost
// 0.3% of a smoothing application's instructions (callgrind, table72_smooth, 2026-11-29).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "engine/simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "engine/level_set/internal.hpp"

namespace marzipan::level_set {

// Godunov |grad phi| with second-order ENO one-sided differences, upwind for speed sign.
// Single precision: the field is stored in floats and the differences are of order 1. The
// scalar form below is the definition; with SSE2, advectionRuns does its float operations in
// its order in four lanes at once (four voxels along x), so the same bits.
#if defined(MARZIPAN_SSE2)
inline __m128 minmod4(__m128 a, __m128 b) {
  const __m128 abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 aSmaller = _mm_cmplt_ps(_mm_and_ps(a, abs), _mm_and_ps(b, abs));
  const __m128 smaller = _mm_or_ps(_mm_and_ps(aSmaller, a), _mm_andnot_ps(aSmaller, b));
  return _mm_andnot_ps(_mm_cmple_ps(_mm_mul_ps(a, b), _mm_setzero_ps()), smaller);
}
#else
inline float minmod(float a, float b) {
  if (a * b <= 0) return 0;
  return std::fabs(a) < std::fabs(b) ? a : b;
}

inline float upwindGradient(const float* v, std::size_t i, const std::size_t stride[3], bool outward) {
  float g2 = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t s = stride[a];
    const float vm2 = v[i - 2 * s], vm1 = v[i - s], v0 = v[i], vp1 = v[i + s], vp2 = v[i + 2 * s];
    const float dm = (v0 - vm1) + 0.5f * minmod(v0 - 2 * vm1 + vm2, vp1 - 2 * v0 + vm1);
    const float dp = (vp1 - v0) - 0.5f * minmod(vp1 - 2 * v0 + vm1, vp2 - 2 * vp1 + v0);
    const float a1 = outward ? std::max(dm, 0.0f) : std::min(dm, 0.0f);
    const float a2 = outward ? std::min(dp, 0.0f) : std::max(dp, 0.0f);
    g2 += a1 * a1 + a2 * a2;
  }
  return std::sqrt(g2);
}
#endif

#if defined(MARZIPAN_SSE2)
// Writes the first n (1..3) lanes of x: a run's last voxels, whose neighbours past the run may
// be another block's.
inline void storePartial(float* out, __m128 x, std::uint32_t n) {
  if (n == 1) {
    _mm_store_ss(out, x);
    return;
  }
  _mm_storel_pi(reinterpret_cast<__m64*>(out), x);
  if (n == 3) _mm_store_ss(out + 2, _mm_movehl_ps(x, x));
}
#endif

// The walk of a sub-step over runs [r, end): voxel j of a run goes to dst[run.first + j] (dst:
// a list-ordered array) or dst[run.index + j] (dst: a grid). lanes(i, k) computes the voxels
// from grid index i = run.index + j, list position k = run.first + j on: with SSE2 four at once
// (an __m128; past the run's end it may read up to 3 voxels and 3 list entries more, which the
// callers provide, and only the run's own are stored), without one (a float). A run of four or
// more (eight or more with AVX2, where a run of five to seven takes a masked eight) ends with the
// four (eight) voxels that end it, stored again over those already stored:
// every voxel is computed alone from v, which dst never is, so the values are the same, and the
// store needs no mask (a run's tail cost as much as its blocks along the band's short rows).
// Kernels hold what they read by value: a store of a vector may alias anything, so the compiler
// would reload whatever they reach by reference after each one.
template <bool kDstIsGrid, class Lanes>
void overRuns(const Run* r, const Run* end, float* dst, Lanes lanes) {
  for (; r != end; ++r) {
    const std::size_t index = r->index, first = r->first, count = r->count;
    float* const out = dst + (kDstIsGrid ? index : first);
    std::size_t j = 0;
#if defined(MARZIPAN_SSE2)
    for (; j + 4 <= count; j += 4) _mm_storeu_ps(out + j, lanes(index + j, first + j));
    if (j < count && count >= 4) {
      _mm_storeu_ps(out + count - 4, lanes(index + count - 4, first + count - 4));
    } else if (j < count) {
      storePartial(out + j, lanes(index + j, first + j), std::uint32_t(count - j));
    }
#else
    for (; j < count; ++j) out[j] = lanes(index + j, first + j);
#endif
  }
}

#if defined(MARZIPAN_AVX2)
// overRuns eight at once (lanes.eight, an __m256), a run of eight or more ending with its last
// eight; a shorter one with its first eight masked when 5 or more, else four (lanes(i, k)): past
// a run's end it reads no further than overRuns.
template <bool kDstIsGrid, class Lanes>
__attribute__((target("avx2"))) void overRunsAvx2(const Run* r, const Run* end, float* dst, Lanes lanes) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (; r != end; ++r) {
    const std::size_t index = r->index, first = r->first, count = r->count;
    float* const out = dst + (kDstIsGrid ? index : first);
    std::size_t j = 0;
    for (; j + 8 <= count; j += 8) _mm256_storeu_ps(out + j, lanes.eight(index + j, first + j));
    const std::size_t left = count - j;
    if (left > 0 && count >= 8) {
      _mm256_storeu_ps(out + count - 8, lanes.eight(index + count - 8, first + count - 8));
    } else if (left > 4) {
      const __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(int(left)), lane);
      _mm256_maskstore_ps(out + j, mask, lanes.eight(index + j, first + j));
    } else if (left == 4) {
      _mm_storeu_ps(out + j, lanes(index + j, first + j));
    } else if (left > 0) {
      storePartial(out + j, lanes(index + j, first + j), std::uint32_t(left));
    }
  }
}
#endif

#if defined(MARZIPAN_SSE2)
// overRuns with the widest lanes the kernels may use now. The destination's kind and (below) a
// curvature limit are template parameters: tested per run and per eight voxels at run time, a
// 70^3 smoothing application ran 0.95M instructions more, a tenth of its 32 sub-steps (callgrind,
// table72_smooth, 2026-11-30).
template <bool kDstIsGrid, class Lanes>
inline void overRunsWidest(const Run* r, const Run* end, float* dst, Lanes lanes) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return overRunsAvx2<kDstIsGrid>(r, end, dst, lanes);
#endif
  overRuns<kDstIsGrid>(r, end, dst, lanes);
}

// curvatureRuns' lanes: operator() four voxels (SSE2), eight() eight (AVX2), each lane the
// definition's operations in its order; kLimited: the Laplacian clamped to +-limit.
template <bool kLimited>
struct CurvatureLanes {
  const float* v;
  const double* factor;
  std::ptrdiff_t sy, sz;
  double limit;

  __m128 operator()(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const double* f = factor + k;
    const __m128d six = _mm_set1_pd(6.0);
    __m128 sum = _mm_add_ps(_mm_loadu_ps(q + 1), _mm_loadu_ps(q - 1));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q + sy));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q - sy));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q + sz));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q - sz));
    const __m128 c = _mm_loadu_ps(q);
    const __m128d c0 = _mm_cvtps_pd(c), c1 = _mm_cvtps_pd(_mm_movehl_ps(c, c));
    __m128d lap0 = _mm_sub_pd(_mm_cvtps_pd(sum), _mm_mul_pd(six, c0));
    __m128d lap1 = _mm_sub_pd(_mm_cvtps_pd(_mm_movehl_ps(sum, sum)), _mm_mul_pd(six, c1));
    if constexpr (kLimited) {
      // std::clamp(x, lo, hi) is (x < lo ? lo : hi < x ? hi : x): max(lo, x), then min(hi, .).
      const __m128d lo = _mm_set1_pd(-limit), hi = _mm_set1_pd(limit);
      lap0 = _mm_min_pd(hi, _mm_max_pd(lo, lap0));
      lap1 = _mm_min_pd(hi, _mm_max_pd(lo, lap1));
    }
    const __m128d out0 = _mm_add_pd(c0, _mm_mul_pd(_mm_loadu_pd(f), lap0));
    const __m128d out1 = _mm_add_pd(c1, _mm_mul_pd(_mm_loadu_pd(f + 2), lap1));
    return _mm_movelh_ps(_mm_cvtpd_ps(out0), _mm_cvtpd_ps(out1));
  }

#if defined(MARZIPAN_AVX2)
  __attribute__((target("avx2"))) __m256 eight(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const double* f = factor + k;
    const __m256d six = _mm256_set1_pd(6.0);
    __m256 sum = _mm256_add_ps(_mm256_loadu_ps(q + 1), _mm256_loadu_ps(q - 1));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q + sy));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q - sy));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q + sz));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q - sz));
    const __m256 c = _mm256_loadu_ps(q);
    const __m256d c0 = _mm256_cvtps_pd(_mm256_castps256_ps128(c)), c1 = _mm256_cvtps_pd(_mm256_extractf128_ps(c, 1));
    __m256d lap0 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(sum)), _mm256_mul_pd(six, c0));
    __m256d lap1 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(sum, 1)), _mm256_mul_pd(six, c1));
    if constexpr (kLimited) {
      const __m256d lo = _mm256_set1_pd(-limit), hi = _mm256_set1_pd(limit);
      lap0 = _mm256_min_pd(hi, _mm256_max_pd(lo, lap0));
      lap1 = _mm256_min_pd(hi, _mm256_max_pd(lo, lap1));
    }
    const __m256d out0 = _mm256_add_pd(c0, _mm256_mul_pd(_mm256_loadu_pd(f), lap0));
    const __m256d out1 = _mm256_add_pd(c1, _mm256_mul_pd(_mm256_loadu_pd(f + 4), lap1));
    return _mm256_set_m128(_mm256_cvtpd_ps(out1), _mm256_cvtpd_ps(out0));
  }
#endif
};

#if defined(MARZIPAN_AVX2)
__attribute__((target("avx2"))) inline __m256 minmod8(__m256 a, __m256 b) {
  const __m256 abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 aSmaller = _mm256_cmp_ps(_mm256_and_ps(a, abs), _mm256_and_ps(b, abs), _CMP_LT_OS);
  const __m256 smaller = _mm256_or_ps(_mm256_and_ps(aSmaller, a), _mm256_andnot_ps(aSmaller, b));
  return _mm256_andnot_ps(_mm256_cmp_ps(_mm256_mul_ps(a, b), _mm256_setzero_ps(), _CMP_LE_OS), smaller);
}
#endif

// advectionRuns' lanes: four voxels along x (SSE2) or eight (AVX2), each lane doing
// upwindGradient's float operations in its order (the axes summed x, y, z onto 0).
// std::max(x, 0) is (x < 0 ? 0 : x), which is _mm_max_ps(0, x) bit for bit (also -0 and NaN);
// std::min(x, 0) likewise _mm_min_ps(0, x).
struct AdvectionLanes {
  const float* v;
  const float* step;
  std::size_t s[3];

  __m128 operator()(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), zero = _mm_setzero_ps();
    const __m128 dtF = _mm_loadu_ps(step + k);
    const __m128 outward = _mm_cmpgt_ps(dtF, zero);
    const __m128 v0 = _mm_loadu_ps(q);
    __m128 g2 = zero;
    for (int a = 0; a < 3; ++a) {
      const __m128 vm2 = _mm_loadu_ps(q - 2 * s[a]), vm1 = _mm_loadu_ps(q - s[a]);
      const __m128 vp1 = _mm_loadu_ps(q + s[a]), vp2 = _mm_loadu_ps(q + 2 * s[a]);
      const __m128 centre = _mm_add_ps(_mm_sub_ps(vp1, _mm_mul_ps(two, v0)), vm1);
      const __m128 dm = _mm_add_ps(_mm_sub_ps(v0, vm1),
                                   _mm_mul_ps(half, minmod4(_mm_add_ps(_mm_sub_ps(v0, _mm_mul_ps(two, vm1)), vm2), centre)));
      const __m128 dp = _mm_sub_ps(_mm_sub_ps(vp1, v0),
                                   _mm_mul_ps(half, minmod4(centre, _mm_add_ps(_mm_sub_ps(vp2, _mm_mul_ps(two, vp1)), v0))));
      const __m128 a1 = _mm_or_ps(_mm_and_ps(outward, _mm_max_ps(zero, dm)), _mm_andnot_ps(outward, _mm_min_ps(zero, dm)));
      const __m128 a2 = _mm_or_ps(_mm_and_ps(outward, _mm_min_ps(zero, dp)), _mm_andnot_ps(outward, _mm_max_ps(zero, dp)));
      g2 = _mm_add_ps(g2, _mm_add_ps(_mm_mul_ps(a1, a1), _mm_mul_ps(a2, a2)));
    }
    return _mm_sub_ps(v0, _mm_mul_ps(dtF, _mm_sqrt_ps(g2)));
  }

#if defined(MARZIPAN_AVX2)
  __attribute__((target("avx2"))) __m256 eight(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const __m256 two = _mm256_set1_ps(2.0f), half = _mm256_set1_ps(0.5f), zero = _mm256_setzero_ps();
    const __m256 dtF = _mm256_loadu_ps(step + k);
    const __m256 outward = _mm256_cmp_ps(dtF, zero, _CMP_GT_OS);
    const __m256 v0 = _mm256_loadu_ps(q);
    __m256 g2 = zero;
    for (int a = 0; a < 3; ++a) {
      const __m256 vm2 = _mm256_loadu_ps(q - 2 * s[a]), vm1 = _mm256_loadu_ps(q - s[a]);
      const __m256 vp1 = _mm256_loadu_ps(q + s[a]), vp2 = _mm256_loadu_ps(q + 2 * s[a]);
      const __m256 centre = _mm256_add_ps(_mm256_sub_ps(vp1, _mm256_mul_ps(two, v0)), vm1);
      const __m256 dm = _mm256_add_ps(
          _mm256_sub_ps(v0, vm1),
          _mm256_mul_ps(half, minmod8(_mm256_add_ps(_mm256_sub_ps(v0, _mm256_mul_ps(two, vm1)), vm2), centre)));
      const __m256 dp = _mm256_sub_ps(
          _mm256_sub_ps(vp1, v0),
          _mm256_mul_ps(half, minmod8(centre, _mm256_add_ps(_mm256_sub_ps(vp2, _mm256_mul_ps(two, vp1)), v0))));
      const __m256 a1 = _mm256_or_ps(_mm256_and_ps(outward, _mm256_max_ps(zero, dm)),
                                     _mm256_andnot_ps(outward, _mm256_min_ps(zero, dm)));
      const __m256 a2 = _mm256_or_ps(_mm256_and_ps(outward, _mm256_min_ps(zero, dp)),
                                     _mm256_andnot_ps(outward, _mm256_max_ps(zero, dp)));
      g2 = _mm256_add_ps(g2, _mm256_add_ps(_mm256_mul_ps(a1, a1), _mm256_mul_ps(a2, a2)));
    }
    return _mm256_sub_ps(v0, _mm256_mul_ps(dtF, _mm256_sqrt_ps(g2)));
  }
#endif
};
#endif

// One explicit curvature step over runs [r, end): dst[run.first + j] (dst: a list-ordered
// array) or dst[run.index + j] (dst: a grid) = phi + dt F L, L = the 7-point Laplacian, from v.
// The neighbours are summed in float in this order and the rest is done in double, as
//   double lap = p[1] + p[-1] + p[sy] + p[-sy] + p[sz] + p[-sz] - 6.0 * p[0];
//   return float(p[0] + factor * std::clamp(lap, -limit, limit));
// would, voxel by voxel (the lanes do the same operations, so the same bits). A run's last
// lanes read up to 3 voxels past it (evolve's region lies kStencilReach inside the grid, so they
// are in it) and factor up to 3 entries past the list (evolve pads it).
inline void curvatureRuns(const float* v, float* dst, bool dstIsGrid, const Run* r, const Run* end, const double* factor,
                   std::ptrdiff_t sy, std::ptrdiff_t sz, double limit) {
  const bool limited = std::isfinite(limit);  // clamping to +-infinity changes nothing
#if defined(MARZIPAN_SSE2)
  const auto run = [&](auto lanes) {
    if (dstIsGrid) return overRunsWidest<true>(r, end, dst, lanes);
    overRunsWidest<false>(r, end, dst, lanes);
  };
  if (limited) return run(CurvatureLanes<true>{v, factor, sy, sz, limit});
  run(CurvatureLanes<false>{v, factor, sy, sz, limit});
#else
  const auto lanes = [=](std::size_t i, std::size_t k) {
    const float* q = v + i;
    double lap = q[1] + q[-1] + q[sy] + q[-sy] + q[sz] + q[-sz] - 6.0 * q[0];
    if (limited) lap = std::clamp(lap, -limit, limit);
    return float(q[0] + factor[k] * lap);
  };
  if (dstIsGrid) return overRuns<true>(r, end, dst, lanes);
  overRuns<false>(r, end, dst, lanes);
#endif
}

// One upwind advection step over runs [r, end): next[run.first + j] = phi - step |grad phi|,
// step = float(dt F), |grad phi| by upwindGradient (outward where step > 0; where step is
// +-0 the direction does not change the result). Reads past a run's end as curvatureRuns.
inline void advectionRuns(const float* v, float* next, const Run* r, const Run* end, const float* step,
                   const std::size_t stride[3]) {
#if defined(MARZIPAN_SSE2)
  overRunsWidest<false>(r, end, next, AdvectionLanes{v, step, {stride[0], stride[1], stride[2]}});
#else
  overRuns<false>(r, end, next, [=](std::size_t i, std::size_t k) {
    return v[i] - step[k] * upwindGradient(v, i, stride, step[k] > 0);
  });
#endif
}

}  // namespace marzipan::level_set
