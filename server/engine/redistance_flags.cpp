// The redistance's flags pass (redistance_flags.hpp).
#include "redistance_flags.hpp"

#include <algorithm>
#include <cstdint>
#include <utility>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "simd_width.hpp"  // MARZIPAN_SSE2, MARZIPAN_AVX2
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

namespace marzipan::redistance_flags {

namespace {

using namespace march_flag;

// f[x] = v[x] < 0 ? pos[x] ^ flip[x] : pos[x] for x < n. A run of 16 voxels or more ends with
// a block that overlaps the one before it (and writes the same bytes again).
[[gnu::always_inline]] inline void signFlags(const float* v, std::uint8_t* f, std::size_t n, const std::uint8_t* pos,
                                             const std::uint8_t* flip) {
#if defined(MARZIPAN_SSE2)
  if (n >= 16) {
    const __m128 zero = _mm_setzero_ps();
    auto block = [&](std::size_t x) __attribute__((always_inline)) {
      const __m128i m0 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x), zero));
      const __m128i m1 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 4), zero));
      const __m128i m2 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 8), zero));
      const __m128i m3 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 12), zero));
      const __m128i neg = _mm_packs_epi16(_mm_packs_epi32(m0, m1), _mm_packs_epi32(m2, m3));  // 0 or -1 each
      const __m128i p = _mm_loadu_si128(reinterpret_cast<const __m128i*>(pos + x));
      const __m128i fl = _mm_loadu_si128(reinterpret_cast<const __m128i*>(flip + x));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(f + x), _mm_xor_si128(p, _mm_and_si128(neg, fl)));
    };
    std::size_t x = 0;
    for (; x + 16 <= n; x += 16) block(x);
    if (x < n) block(n - 16);
    return;
  }
#endif
  for (std::size_t x = 0; x < n; ++x) f[x] = std::uint8_t(pos[x] ^ (v[x] < 0 ? flip[x] : 0));
}

#if defined(MARZIPAN_AVX2)
// signFlags' 32 voxels from x on with AVX2: the same bytes.
[[gnu::always_inline]] __attribute__((target("avx2"))) inline void signBlockAvx2(const float* v, std::uint8_t* f,
                                                                               const std::uint8_t* pos,
                                                                               const std::uint8_t* flip, std::size_t x) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256i m0 = _mm256_castps_si256(_mm256_cmp_ps(_mm256_loadu_ps(v + x), zero, _CMP_LT_OS));
  const __m256i m1 = _mm256_castps_si256(_mm256_cmp_ps(_mm256_loadu_ps(v + x + 8), zero, _CMP_LT_OS));
  const __m256i m2 = _mm256_castps_si256(_mm256_cmp_ps(_mm256_loadu_ps(v + x + 16), zero, _CMP_LT_OS));
  const __m256i m3 = _mm256_castps_si256(_mm256_cmp_ps(_mm256_loadu_ps(v + x + 24), zero, _CMP_LT_OS));
  // The packs work within 128-bit halves: their 4-byte groups come out as m0 m1 m2 m3 of the
  // low halves, then of the high ones, which the permutation puts back in order.
  const __m256i packed = _mm256_packs_epi16(_mm256_packs_epi32(m0, m1), _mm256_packs_epi32(m2, m3));
  const __m256i neg = _mm256_permutevar8x32_epi32(packed, _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7));
  const __m256i p = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(pos + x));
  const __m256i fl = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(flip + x));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(f + x), _mm256_xor_si256(p, _mm256_and_si256(neg, fl)));
}

// signFlags 32 voxels at a time (a slice of a stroke's box is a few thousand), ending with a
// block that overlaps the one before; shorter runs are signFlags'.
__attribute__((target("avx2"))) void signFlagsAvx2(const float* v, std::uint8_t* f, std::size_t n,
                                                   const std::uint8_t* pos, const std::uint8_t* flip) {
  if (n < 32) return signFlags(v, f, n, pos, flip);
  std::size_t x = 0;
  for (; x + 32 <= n; x += 32) signBlockAvx2(v, f, pos, flip, x);
  if (x < n) signBlockAvx2(v, f, pos, flip, n - 32);
}
#endif

// Adds delta to the counts of box b's positions in a slice (b grid-local, x fastest).
void countBox(std::uint16_t* count, std::size_t sx, const Box& b, std::uint16_t delta) {
  for (int y = b.lo.y; y < b.hi.y; ++y) {
    std::uint16_t* row = count + std::size_t(y) * sx;
    for (int x = b.lo.x; x < b.hi.x; ++x) row[x] = std::uint16_t(row[x] + delta);
  }
}

// The two bytes of n voxel positions (flags = pos, or pos ^ flip where the value is negative)
// from the boxes' counts and the interior bits (null: none), as FlagLayout puts them.
void flagPattern(std::size_t n, const std::uint16_t* reset, const std::uint16_t* marked, const std::uint8_t* interior,
                 std::uint8_t base, std::uint8_t resetPos, std::uint8_t resetFlip, std::uint8_t* pos, std::uint8_t* flip) {
  std::size_t x = 0;
#if defined(MARZIPAN_SSE2)
  const __m128i zero = _mm_setzero_si128(), baseV = _mm_set1_epi8(char(base));
  const __m128i resetPosV = _mm_set1_epi8(char(resetPos)), resetFlipV = _mm_set1_epi8(char(resetFlip));
  const __m128i negV = _mm_set1_epi8(char(kNeg)), markedV = _mm_set1_epi8(char(kMarked));
  auto none = [&](const std::uint16_t* c) __attribute__((always_inline)) {  // 0xff where no box holds it
    const __m128i a = _mm_cmpeq_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + x)), zero);
    const __m128i b = _mm_cmpeq_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + x + 8)), zero);
    return _mm_packs_epi16(a, b);
  };
  for (; x + 16 <= n; x += 16) {
    const __m128i outside = none(reset), unmarked = none(marked);
    __m128i p = _mm_or_si128(_mm_andnot_si128(outside, resetPosV), _mm_and_si128(outside, baseV));
    p = _mm_or_si128(p, _mm_andnot_si128(unmarked, markedV));
    if (interior) p = _mm_or_si128(p, _mm_loadu_si128(reinterpret_cast<const __m128i*>(interior + x)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(pos + x), p);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(flip + x),
                     _mm_or_si128(_mm_andnot_si128(outside, resetFlipV), _mm_and_si128(outside, negV)));
  }
#endif
  for (; x < n; ++x) {
    const bool inReset = reset[x] != 0;
    pos[x] = std::uint8_t((inReset ? resetPos : base) | (interior ? interior[x] : 0) | (marked[x] != 0 ? kMarked : 0));
    flip[x] = inReset ? resetFlip : kNeg;
  }
}

#if defined(MARZIPAN_AVX2)
// flagPattern 32 positions at a time with AVX2 (the rest as flagPattern does them): the same
// bytes.
__attribute__((target("avx2"))) void flagPatternAvx2(std::size_t n, const std::uint16_t* reset,
                                                     const std::uint16_t* marked, const std::uint8_t* interior,
                                                     std::uint8_t base, std::uint8_t resetPos, std::uint8_t resetFlip,
                                                     std::uint8_t* pos, std::uint8_t* flip) {
  const __m256i zero = _mm256_setzero_si256(), baseV = _mm256_set1_epi8(char(base));
  const __m256i resetPosV = _mm256_set1_epi8(char(resetPos)), resetFlipV = _mm256_set1_epi8(char(resetFlip));
  const __m256i negV = _mm256_set1_epi8(char(kNeg)), markedV = _mm256_set1_epi8(char(kMarked));
  std::size_t x = 0;
  for (; x + 32 <= n; x += 32) {
    // 0xff where no box holds the position: the packs work within 128-bit halves, whose 8-byte
    // groups the permutation puts back in order.
    const auto none = [&](const std::uint16_t* c) __attribute__((always_inline, target("avx2"))) {
      const __m256i a = _mm256_cmpeq_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(c + x)), zero);
      const __m256i b = _mm256_cmpeq_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(c + x + 16)), zero);
      return _mm256_permute4x64_epi64(_mm256_packs_epi16(a, b), 0xd8);
    };
    const __m256i outside = none(reset), unmarked = none(marked);
    __m256i p = _mm256_or_si256(_mm256_andnot_si256(outside, resetPosV), _mm256_and_si256(outside, baseV));
    p = _mm256_or_si256(p, _mm256_andnot_si256(unmarked, markedV));
    if (interior) p = _mm256_or_si256(p, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(interior + x)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(pos + x), p);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(flip + x),
                        _mm256_or_si256(_mm256_andnot_si256(outside, resetFlipV), _mm256_and_si256(outside, negV)));
  }
  if (x < n)
    flagPattern(n - x, reset + x, marked + x, interior ? interior + x : nullptr, base, resetPos, resetFlip, pos + x,
                flip + x);
}
#endif

}  // namespace

void flagSlices(const DenseGrid& g, std::uint8_t* flags, const FlagLayout& layout, int z0, int z1, FlagPiece& fp,
                const ProgressShare& progress) {
  const int sx = g.size.x, sy = g.size.y, sz = g.size.z;
  const int xLo = std::min(2, sx), xHi = std::max(xLo, sx - 2);
  const int yLo = std::min(2, sy), yHi = std::max(yLo, sy - 2);
  const std::uint8_t resetPos = std::uint8_t(kReset | (layout.exactSide > 0 ? kKnown | kFrozen : 0));
  const std::uint8_t resetFlip = std::uint8_t(kNeg | (layout.exactSide != 0 ? kKnown | kFrozen : 0));
  const std::size_t n = g.sxy;
  fp.resetCount.assign(n, 0);
  fp.markedCount.assign(n, 0);
  fp.interior.assign(n, 0);
  for (int y = yLo; y < yHi; ++y)
    std::fill_n(fp.interior.begin() + std::ptrdiff_t(std::size_t(y) * g.sx + std::size_t(xLo)), xHi - xLo, kInterior);
  // Box b grid-local as its slices' rectangles, and whether it holds slice vz (an empty box none).
  auto local = [&](const Box& b) {
    return Box{{b.lo.x - g.box.lo.x, b.lo.y - g.box.lo.y, 0}, {b.hi.x - g.box.lo.x, b.hi.y - g.box.lo.y, 1}};
  };
  auto holds = [](const Box& b, int vz) { return vz >= b.lo.z && vz < b.hi.z && b.lo.x < b.hi.x && b.lo.y < b.hi.y; };
  fp.pos.resize(n);
  fp.flip.resize(n);
  const float* v = g.v.data();
  bool lastInner = false;
  for (int z = z0; z < z1; ++z) {
    progress.check();
    const int vz = g.box.lo.z + z;
    const bool innerZ = z >= 2 && z + 2 < sz;
    // The rows whose pattern changes: those of the boxes that begin or end here, or all.
    int y0 = z == z0 || innerZ != lastInner ? 0 : sy, y1 = z == z0 || innerZ != lastInner ? sy : 0;
    lastInner = innerZ;
    for (const auto& [boxes, count] : {std::pair{layout.reset, fp.resetCount.data()}, std::pair{layout.marked, fp.markedCount.data()}})
      for (const Box& b : boxes) {
        const bool now = holds(b, vz), before = z > z0 && holds(b, vz - 1);
        if (now == before) continue;
        const Box l = local(b);
        countBox(count, g.sx, l, std::uint16_t(now ? 1 : 0xffff));
        y0 = std::min(y0, l.lo.y);
        y1 = std::max(y1, l.hi.y);
      }
    if (y0 < y1) {
      const std::size_t from = std::size_t(y0) * g.sx;
#if defined(MARZIPAN_AVX2)
      const auto pattern = simd_width::useAvx2() ? flagPatternAvx2 : flagPattern;
#else
      const auto pattern = flagPattern;
#endif
      pattern(std::size_t(y1 - y0) * g.sx, fp.resetCount.data() + from, fp.markedCount.data() + from,
              innerZ ? fp.interior.data() + from : nullptr, layout.base, resetPos, resetFlip, fp.pos.data() + from,
              fp.flip.data() + from);
    }
    const std::size_t slice = std::size_t(z) * n;
#if defined(MARZIPAN_AVX2)
    if (simd_width::useAvx2()) {
      signFlagsAvx2(v + slice, flags + slice, n, fp.pos.data(), fp.flip.data());
      continue;
    }
#endif
    signFlags(v + slice, flags + slice, n, fp.pos.data(), fp.flip.data());
  }
}

}  // namespace marzipan::redistance_flags
