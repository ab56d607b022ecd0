// A brick's slices as 64-bit words, shared by the splat extraction (splats.cpp) and the
// listing of the bricks around a change (splats_around.cpp): bit x + 8 y of a slice's word is
// voxel (x, y) of that slice of the brick (Bricks::index order), for its inside bit (d < 0), its
// near bit (|d| < kSurfaceNear) or whether it lies in the domain. Comparisons only, so the SSE2
// and AVX2 forms (simd_width.hpp) give the scalar definitions' bits. Internal to the engine; the
// functions are inline so that both files keep them inlined in their per-slice loops.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "simd_width.hpp"  // MARZIPAN_SSE2, MARZIPAN_AVX2
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "splats.hpp"
#include "volume.hpp"

namespace marzipan::splat_slices {

// Internal linkage: each file has its own copy, which the compiler inlines as it did when they
// were the extraction's own (as inline functions of one definition, 0.4% more instructions a
// splat delta).
namespace {

static_assert(kBrickSide == 8, "a brick slice is one 64-bit word");

inline bool inGrid(const Volume& vol, Int3 b) {
  const Int3 n = vol.brickDims();
  return b.x >= 0 && b.y >= 0 && b.z >= 0 && b.x < n.x && b.y < n.y && b.z < n.z;
}

#if defined(MARZIPAN_SSE2)
// Sixteen floats from v as bytes: all ones where v < 0 (inBytes) and where |v| < kSurfaceNear
// (nearBytes), zero elsewhere; the comparisons' all-ones lanes narrowed by saturating packs (-1
// stays -1).
inline void classify16(const float* v, __m128i& inBytes, __m128i& nearBytes) {
  const __m128 zero = _mm_setzero_ps(), nearBound = _mm_set1_ps(kSurfaceNear);
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  __m128i in[4], nr[4];
  for (int k = 0; k < 4; ++k) {
    const __m128 x = _mm_loadu_ps(v + 4 * k);
    in[k] = _mm_castps_si128(_mm_cmplt_ps(x, zero));
    nr[k] = _mm_castps_si128(_mm_cmplt_ps(_mm_and_ps(x, magnitude), nearBound));
  }
  inBytes = _mm_packs_epi16(_mm_packs_epi32(in[0], in[1]), _mm_packs_epi32(in[2], in[3]));
  nearBytes = _mm_packs_epi16(_mm_packs_epi32(nr[0], nr[1]), _mm_packs_epi32(nr[2], nr[3]));
}
#endif

inline constexpr std::uint64_t kColumn0 = 0x0101010101010101ull, kColumn7 = kColumn0 << 7, kRow0 = 0xffull,
                        kRow7 = kRow0 << 56;

// Bit x + 8 y of domain[z]: voxel (x, y, z) of brick b lies in the domain.
inline void domainSlices(const Volume& vol, Int3 b, std::uint64_t domain[kBrickSide]) {
  const Int3 o = Bricks::origin(b), dims = vol.dims();
  const int xs = std::min(kBrickSide, dims.x - o.x), ys = std::min(kBrickSide, dims.y - o.y);
  std::uint64_t slice = ~std::uint64_t(0);
  if (xs < kBrickSide || ys < kBrickSide) {
    slice = 0;
    for (int y = 0; y < ys; ++y) slice |= ((std::uint64_t(1) << xs) - 1) << (kBrickSide * y);
  }
  for (int z = 0; z < kBrickSide; ++z) domain[z] = o.z + z < dims.z ? slice : 0;
}

#if defined(MARZIPAN_AVX2)
// sliceBits thirty-two floats at a time: the comparisons' lanes narrowed by packs, which
// interleave the 128-bit halves, then put back in order by a permutation of 32-bit groups.
__attribute__((target("avx2"))) inline void sliceBitsAvx2(const float* v, std::uint64_t& inside, std::uint64_t& near) {
  const __m256 zero = _mm256_setzero_ps(), nearBound = _mm256_set1_ps(kSurfaceNear);
  const __m256 magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
  std::uint64_t in = 0, nr = 0;
  for (int i = 0; i < kBrickSide * kBrickSide; i += 32) {
    __m256i a[4], b[4];
    for (int k = 0; k < 4; ++k) {
      const __m256 x = _mm256_loadu_ps(v + i + 8 * k);
      a[k] = _mm256_castps_si256(_mm256_cmp_ps(x, zero, _CMP_LT_OQ));
      b[k] = _mm256_castps_si256(_mm256_cmp_ps(_mm256_and_ps(x, magnitude), nearBound, _CMP_LT_OQ));
    }
    const __m256i inBytes = _mm256_permutevar8x32_epi32(
        _mm256_packs_epi16(_mm256_packs_epi32(a[0], a[1]), _mm256_packs_epi32(a[2], a[3])), order);
    const __m256i nearBytes = _mm256_permutevar8x32_epi32(
        _mm256_packs_epi16(_mm256_packs_epi32(b[0], b[1]), _mm256_packs_epi32(b[2], b[3])), order);
    in |= std::uint64_t(std::uint32_t(_mm256_movemask_epi8(inBytes))) << i;
    nr |= std::uint64_t(std::uint32_t(_mm256_movemask_epi8(nearBytes))) << i;
  }
  inside = in;
  near = nr;
}
#endif

// Inside and near bits of the 64 voxels of slice z of a brick's data.
inline void sliceBits(const float* v, std::uint64_t& inside, std::uint64_t& near) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return sliceBitsAvx2(v, inside, near);
#endif
  std::uint64_t in = 0, nr = 0;
#if defined(MARZIPAN_SSE2)
  for (int i = 0; i < kBrickSide * kBrickSide; i += 16) {
    __m128i inBytes, nearBytes;
    classify16(v + i, inBytes, nearBytes);
    in |= std::uint64_t(std::uint32_t(_mm_movemask_epi8(inBytes))) << i;
    nr |= std::uint64_t(std::uint32_t(_mm_movemask_epi8(nearBytes))) << i;
  }
#else
  for (int i = 0; i < kBrickSide * kBrickSide; ++i) {
    in |= std::uint64_t(v[i] < 0) << i;
    nr |= std::uint64_t(std::fabs(v[i]) < kSurfaceNear) << i;
  }
#endif
  inside = in;
  near = nr;
}

// sliceBits of slice z of a brick whose data is `data`, or whose every voxel reads `uniform`
// (data null), kept to its voxels in the domain (`domain`, domainSlices()'s word of z).
inline void brickSliceBits(const float* data, float uniform, int z, std::uint64_t domain, std::uint64_t& inside,
                    std::uint64_t& near) {
  if (data) {
    sliceBits(data + Bricks::index(0, 0, z), inside, near);
  } else {
    inside = uniform < 0 ? ~std::uint64_t(0) : 0;
    near = std::fabs(uniform) < kSurfaceNear ? ~std::uint64_t(0) : 0;
  }
  inside &= domain;
  near &= domain;
}

// Bit i: v[i] < 0, over the 8 floats of a brick row.
inline std::uint32_t rowInside(const float* v) {
#if defined(MARZIPAN_SSE2)
  const __m128 zero = _mm_setzero_ps();
  return std::uint32_t(_mm_movemask_ps(_mm_cmplt_ps(_mm_loadu_ps(v), zero)) |
                       _mm_movemask_ps(_mm_cmplt_ps(_mm_loadu_ps(v + 4), zero)) << 4);
#else
  std::uint32_t m = 0;
  for (int i = 0; i < kBrickSide; ++i) m |= std::uint32_t(v[i] < 0) << i;
  return m;
#endif
}

// Bit 8 y: v[stride y] < 0, for y in [0, kBrickSide) (a column of a slice: the bits of x = 0 of
// a slice word; shifted left by kBrickSide - 1, of x = kBrickSide - 1).
inline std::uint64_t columnInside(const float* v, int stride) {
  std::uint32_t m = 0;
#if defined(MARZIPAN_SSE2)
  const __m128 zero = _mm_setzero_ps();
  const __m128 lo = _mm_set_ps(v[3 * stride], v[2 * stride], v[stride], v[0]),
               hi = _mm_set_ps(v[7 * stride], v[6 * stride], v[5 * stride], v[4 * stride]);
  m = std::uint32_t(_mm_movemask_ps(_mm_cmplt_ps(lo, zero)) | _mm_movemask_ps(_mm_cmplt_ps(hi, zero)) << 4);
#else
  for (int y = 0; y < kBrickSide; ++y) m |= std::uint32_t(v[stride * y] < 0) << y;
#endif
  // Bit y of m to bit 8 y: m copied into every byte, byte y keeps its bit y, a byte that is not
  // zero sets its top bit (adding 0x7f carries no further), shifted down to the byte's bottom.
  const std::uint64_t kept = (std::uint64_t(m) * 0x0101010101010101ull) & 0x8040201008040201ull;
  return (((kept + 0x7f7f7f7f7f7f7f7full) | kept) & 0x8080808080808080ull) >> 7;
}

}  // namespace

}  // namespace marzipan::splat_slices
