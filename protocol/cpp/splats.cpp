// The splat wire codec. Byte layout and quantization: see splats.hpp.
//
// Speed: where the build has SSE2 the encoder quantizes four points at a time, and eight in
// AVX2 where splat_width.hpp allows it, lane by lane the same float operations in the same
// order as the one-point encodePoint (which takes the rest of a block), so all write the same
// bytes.
#include "splats.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#if defined(__SSE2__) && !defined(MARZIPAN_SCALAR_KERNELS)
#include <emmintrin.h>
#define MARZIPAN_SPLATS_SSE2 1
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define MARZIPAN_SPLATS_AVX2 1
#endif
#endif

#include "protocol/cpp/cpu.hpp"
#include "protocol/cpp/errors.hpp"
#include "protocol/cpp/little_endian.hpp"
#include "protocol/cpp/splat_width.hpp"

namespace marzipan {

namespace {

constexpr int kPosBits = kSplatPositionBits;
constexpr int kPosMax = kSplatPositionMax;
constexpr float kPosLow = kSplatPositionLow;
constexpr float kPosStep = kSplatPositionStep;
constexpr int kOctBits = 11;
constexpr int kOctMax = (1 << kOctBits) - 1;
constexpr int kMaxPointsPerBrick = kSplatBrickSide * kSplatBrickSide * kSplatBrickSide;

using namespace le;

constexpr std::uint8_t kMagic[4] = {'M', 'Z', 'S', 'P'};

float signOrPlus(float v) { return v < 0 ? -1.0f : 1.0f; }

std::uint32_t positionCode(float q, float origin) {
  const float t = std::clamp((q - origin - kPosLow) * (1 / kPosStep), 0.0f, float(kPosMax));
  return std::uint32_t(t + 0.5f);
}

// A normal so short that 1 / l1 overflows (subnormal components: no tool makes one, but the
// codec takes any finite splat) is first scaled by 2^64, which keeps its direction, all that is
// encoded: unscaled, inf * 0 made a NaN whose conversion to an integer is undefined (UBSan).
constexpr float kTinyNormalScale = 0x1p64f;

std::uint64_t encodePoint(const Splat& s, Int3 origin) {
  float u = 0, v = 0;
  float nx = s.nx, ny = s.ny, nz = s.nz;
  float l1 = std::fabs(nx) + std::fabs(ny) + std::fabs(nz);
  if (l1 > 0 && !(1 / l1 <= std::numeric_limits<float>::max())) {
    nx *= kTinyNormalScale, ny *= kTinyNormalScale, nz *= kTinyNormalScale;
    l1 = std::fabs(nx) + std::fabs(ny) + std::fabs(nz);
  }
  if (l1 > 0) {
    const float inv = 1 / l1;
    u = nx * inv;
    v = ny * inv;
    if (nz < 0) {
      const float fu = (1 - std::fabs(v)) * signOrPlus(u), fv = (1 - std::fabs(u)) * signOrPlus(v);
      u = fu;
      v = fv;
    }
  }
  const auto oct = [](float c) {
    return std::uint64_t(std::clamp((c + 1) * (float(kOctMax) / 2), 0.0f, float(kOctMax)) + 0.5f);
  };
  return std::uint64_t(positionCode(s.x, float(origin.x))) |
         std::uint64_t(positionCode(s.y, float(origin.y))) << kPosBits |
         std::uint64_t(positionCode(s.z, float(origin.z))) << (2 * kPosBits) | oct(u) << (3 * kPosBits) |
         oct(v) << (3 * kPosBits + kOctBits);
}

#if defined(MARZIPAN_SPLATS_SSE2)
// clamp(t, 0, hi) + 0.5 truncated, lane by lane, as the scalar code's integer conversions of
// std::clamp(t, 0.0f, hi) + 0.5f: the same value for every finite t (a -0 that clamp keeps
// and max turns into +0 gives the same 0.5).
inline __m128i roundedCode(__m128 t, float hi) {
  const __m128 c = _mm_min_ps(_mm_max_ps(t, _mm_setzero_ps()), _mm_set1_ps(hi));
  return _mm_cvttps_epi32(_mm_add_ps(c, _mm_set1_ps(0.5f)));
}

// The words of four points, bits 0..31 in lo's lanes and 32..63 in hi's, as little-endian u64
// at p, `stride` bytes apart.
void storeWords4(__m128i lo, __m128i hi, std::uint8_t* p, std::size_t stride) {
  const __m128i first = _mm_unpacklo_epi32(lo, hi), second = _mm_unpackhi_epi32(lo, hi);
  _mm_storel_epi64(reinterpret_cast<__m128i*>(p), first);
  _mm_storel_epi64(reinterpret_cast<__m128i*>(p + stride), _mm_unpackhi_epi64(first, first));
  _mm_storel_epi64(reinterpret_cast<__m128i*>(p + 2 * stride), second);
  _mm_storel_epi64(reinterpret_cast<__m128i*>(p + 3 * stride), _mm_unpackhi_epi64(second, second));
}

// encodePoint for the four splats at s, lane by lane the same float operations in the same
// order, written as four little-endian u64 at p (`stride` bytes apart). False, with nothing
// written, when a normal is so short that 1 / l1 overflows (subnormal components), which the
// scalar code scales first (kTinyNormalScale).
bool encodePoints4(const Splat* s, Int3 origin, std::uint8_t* p, std::size_t stride) {
  static_assert(sizeof(Splat) == 6 * sizeof(float), "a splat is six packed floats");
  // Each splat as three pairs (x, y), (z, nx), (ny, nz); two splats' pairs to a register, then
  // the four splats' values per field.
  const auto pair = [&](int k, int f) {
    return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(reinterpret_cast<const float*>(s + k) + 2 * f));
  };
  __m128 field[6];
  for (int f = 0; f < 3; ++f) {
    const __m128 lo = _mm_castsi128_ps(_mm_unpacklo_epi64(pair(0, f), pair(1, f)));
    const __m128 hi = _mm_castsi128_ps(_mm_unpacklo_epi64(pair(2, f), pair(3, f)));
    field[2 * f] = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
    field[2 * f + 1] = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
  }
  const __m128 low = _mm_set1_ps(kPosLow), scale = _mm_set1_ps(1 / kPosStep);
  const auto position = [&](__m128 q, int o) {
    return roundedCode(_mm_mul_ps(_mm_sub_ps(_mm_sub_ps(q, _mm_set1_ps(float(o))), low), scale), float(kPosMax));
  };
  const __m128i x = position(field[0], origin.x), y = position(field[1], origin.y), z = position(field[2], origin.z);

  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f), minusOne = _mm_set1_ps(-1.0f);
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 nx = field[3], ny = field[4], nz = field[5];
  const __m128 l1 = _mm_add_ps(_mm_add_ps(_mm_and_ps(nx, magnitude), _mm_and_ps(ny, magnitude)), _mm_and_ps(nz, magnitude));
  const __m128 some = _mm_cmpgt_ps(l1, zero);
  const __m128 inv = _mm_div_ps(one, l1);
  if (_mm_movemask_ps(_mm_and_ps(some, _mm_cmpeq_ps(inv, _mm_set1_ps(std::numeric_limits<float>::infinity())))) != 0)
    return false;
  __m128 u = _mm_and_ps(some, _mm_mul_ps(nx, inv)), v = _mm_and_ps(some, _mm_mul_ps(ny, inv));
  const auto signOrPlus4 = [&](__m128 c) {
    const __m128 negative = _mm_cmplt_ps(c, zero);
    return _mm_or_ps(_mm_and_ps(negative, minusOne), _mm_andnot_ps(negative, one));
  };
  const __m128 fu = _mm_mul_ps(_mm_sub_ps(one, _mm_and_ps(v, magnitude)), signOrPlus4(u));
  const __m128 fv = _mm_mul_ps(_mm_sub_ps(one, _mm_and_ps(u, magnitude)), signOrPlus4(v));
  const __m128 lower = _mm_cmplt_ps(nz, zero);  // only where l1 > 0
  u = _mm_or_ps(_mm_and_ps(lower, fu), _mm_andnot_ps(lower, u));
  v = _mm_or_ps(_mm_and_ps(lower, fv), _mm_andnot_ps(lower, v));
  const __m128 octScale = _mm_set1_ps(float(kOctMax) / 2);
  const __m128i cu = roundedCode(_mm_mul_ps(_mm_add_ps(u, one), octScale), float(kOctMax));
  const __m128i cv = roundedCode(_mm_mul_ps(_mm_add_ps(v, one), octScale), float(kOctMax));

  // Bits 0..31 and 32..63 of each point's word (Z straddles them).
  const __m128i lo = _mm_or_si128(_mm_or_si128(x, _mm_slli_epi32(y, kPosBits)), _mm_slli_epi32(z, 2 * kPosBits));
  const __m128i hi = _mm_or_si128(_mm_or_si128(_mm_srli_epi32(z, 32 - 2 * kPosBits), _mm_slli_epi32(cu, 3 * kPosBits - 32)),
                                  _mm_slli_epi32(cv, 3 * kPosBits + kOctBits - 32));
  storeWords4(lo, hi, p, stride);
  return true;
}
#endif

#if defined(MARZIPAN_SPLATS_AVX2)
// encodePoints4 for eight splats: each field's eight values gathered (one instruction a field),
// then the same float operations in the same order on eight lanes, and the two halves' words
// written as encodePoints4 writes its four. False, with nothing written, as encodePoints4.
__attribute__((target("avx2"))) bool encodePoints8(const Splat* s, Int3 origin, std::uint8_t* p, std::size_t stride) {
  static_assert(sizeof(Splat) == 6 * sizeof(float), "a splat is six packed floats");
  const float* f = reinterpret_cast<const float*>(s);
  const __m256i splat = _mm256_setr_epi32(0, 6, 12, 18, 24, 30, 36, 42);
  const __m256 zero = _mm256_setzero_ps(), half = _mm256_set1_ps(0.5f);
  // clamp(t, 0, hi) + 0.5 truncated, as roundedCode.
  const __m256 posMax = _mm256_set1_ps(float(kPosMax)), octMax = _mm256_set1_ps(float(kOctMax));
  const __m256 low = _mm256_set1_ps(kPosLow), scale = _mm256_set1_ps(1 / kPosStep);
  __m256i code[3];
  const int o[3] = {origin.x, origin.y, origin.z};
  for (int a = 0; a < 3; ++a) {
    const __m256 q = _mm256_i32gather_ps(f + a, splat, 4);
    const __m256 t = _mm256_mul_ps(_mm256_sub_ps(_mm256_sub_ps(q, _mm256_set1_ps(float(o[a]))), low), scale);
    code[a] = _mm256_cvttps_epi32(_mm256_add_ps(_mm256_min_ps(_mm256_max_ps(t, zero), posMax), half));
  }

  const __m256 one = _mm256_set1_ps(1.0f), minusOne = _mm256_set1_ps(-1.0f);
  const __m256 magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 nx = _mm256_i32gather_ps(f + 3, splat, 4), ny = _mm256_i32gather_ps(f + 4, splat, 4),
               nz = _mm256_i32gather_ps(f + 5, splat, 4);
  const __m256 l1 = _mm256_add_ps(_mm256_add_ps(_mm256_and_ps(nx, magnitude), _mm256_and_ps(ny, magnitude)),
                                  _mm256_and_ps(nz, magnitude));
  const __m256 some = _mm256_cmp_ps(l1, zero, _CMP_GT_OS);
  const __m256 inv = _mm256_div_ps(one, l1);
  if (_mm256_movemask_ps(_mm256_and_ps(
          some, _mm256_cmp_ps(inv, _mm256_set1_ps(std::numeric_limits<float>::infinity()), _CMP_EQ_OQ))) != 0)
    return false;
  __m256 u = _mm256_and_ps(some, _mm256_mul_ps(nx, inv)), v = _mm256_and_ps(some, _mm256_mul_ps(ny, inv));
  const __m256 signU = _mm256_blendv_ps(one, minusOne, _mm256_cmp_ps(u, zero, _CMP_LT_OS));
  const __m256 signV = _mm256_blendv_ps(one, minusOne, _mm256_cmp_ps(v, zero, _CMP_LT_OS));
  const __m256 fu = _mm256_mul_ps(_mm256_sub_ps(one, _mm256_and_ps(v, magnitude)), signU);
  const __m256 fv = _mm256_mul_ps(_mm256_sub_ps(one, _mm256_and_ps(u, magnitude)), signV);
  const __m256 lower = _mm256_cmp_ps(nz, zero, _CMP_LT_OS);  // only where l1 > 0
  u = _mm256_blendv_ps(u, fu, lower);
  v = _mm256_blendv_ps(v, fv, lower);
  const __m256 octScale = _mm256_set1_ps(float(kOctMax) / 2);
  const __m256i cu = _mm256_cvttps_epi32(
      _mm256_add_ps(_mm256_min_ps(_mm256_max_ps(_mm256_mul_ps(_mm256_add_ps(u, one), octScale), zero), octMax), half));
  const __m256i cv = _mm256_cvttps_epi32(
      _mm256_add_ps(_mm256_min_ps(_mm256_max_ps(_mm256_mul_ps(_mm256_add_ps(v, one), octScale), zero), octMax), half));

  const __m256i lo = _mm256_or_si256(_mm256_or_si256(code[0], _mm256_slli_epi32(code[1], kPosBits)),
                                     _mm256_slli_epi32(code[2], 2 * kPosBits));
  const __m256i hi = _mm256_or_si256(
      _mm256_or_si256(_mm256_srli_epi32(code[2], 32 - 2 * kPosBits), _mm256_slli_epi32(cu, 3 * kPosBits - 32)),
      _mm256_slli_epi32(cv, 3 * kPosBits + kOctBits - 32));
  storeWords4(_mm256_castsi256_si128(lo), _mm256_castsi256_si128(hi), p, stride);
  storeWords4(_mm256_extracti128_si256(lo, 1), _mm256_extracti128_si256(hi, 1), p + 4 * stride, stride);
  return true;
}

std::atomic<bool> useAvx2{splat_width::avx2Available()};
#endif

Splat decodePoint(std::uint64_t w, Int3 origin) {
  Splat s;
  s.x = float(origin.x) + kPosLow + float(w & kPosMax) * kPosStep;
  s.y = float(origin.y) + kPosLow + float((w >> kPosBits) & kPosMax) * kPosStep;
  s.z = float(origin.z) + kPosLow + float((w >> (2 * kPosBits)) & kPosMax) * kPosStep;
  // (2U - 2047) / 2047 rather than 2U / 2047 - 1: the same value, but codes mirrored around
  // the middle give exactly opposite floats, so both codes of the folded seam decode alike.
  float u = float(2 * int((w >> (3 * kPosBits)) & kOctMax) - kOctMax) / float(kOctMax);
  float v = float(2 * int(w >> (3 * kPosBits + kOctBits)) - kOctMax) / float(kOctMax);
  const float z = 1 - std::fabs(u) - std::fabs(v);
  if (z < 0) {
    const float fu = (1 - std::fabs(v)) * signOrPlus(u), fv = (1 - std::fabs(u)) * signOrPlus(v);
    u = fu;
    v = fv;
  }
  const float inv = 1 / std::sqrt(u * u + v * v + z * z);
  s.nx = u * inv;
  s.ny = v * inv;
  s.nz = z * inv;
  return s;
}

[[noreturn]] void formatError(const std::string& message) { throw EngineError(ErrorKind::Format, "splats", message); }

void checkVersion(std::uint16_t version) {
  if (version != kSplatFormatVersionPlain && version != kSplatFormatVersion)
    throw EngineError(ErrorKind::InvalidArgument, "version", "splat buffers have versions 1 and 2");
}

// Whether the brick's block carries texels in `version`.
bool paintedIn(const BrickSplats& b, std::uint16_t version) {
  return version >= 2 && !b.texels.empty() && !b.points.empty();
}

std::size_t blockSize(const BrickSplats& b, std::uint16_t version) {
  return kSplatBrickHeaderBytes + (paintedIn(b, version) ? kSplatPaintedPointBytes : kSplatPointBytes) * b.points.size();
}

}  // namespace

std::size_t encodedSplatsSize(const std::vector<BrickSplats>& bricks, std::uint16_t version) {
  checkVersion(version);
  std::size_t n = kSplatHeaderBytes;
  for (const auto& b : bricks) n += blockSize(b, version);
  return n;
}

namespace {

// Whether every position and normal is finite: no float with all exponent bits set.
#if defined(MARZIPAN_SPLATS_AVX2)
// Whether the first 8 * (floats / 8) floats at bytes are finite; *done: that count.
__attribute__((target("avx2"))) bool allFiniteAvx2(const std::uint8_t* bytes, std::size_t floats, std::size_t* done) {
  const __m256i exponent = _mm256_set1_epi32(0x7f800000);
  __m256i bad = _mm256_setzero_si256();
  std::size_t i = 0;
  for (; i + 8 <= floats; i += 8) {
    const __m256i w = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(bytes + 4 * i));
    bad = _mm256_or_si256(bad, _mm256_cmpeq_epi32(_mm256_and_si256(w, exponent), exponent));
  }
  *done = i;
  return _mm256_movemask_epi8(bad) == 0;
}
#endif

bool allFinite(const std::vector<Splat>& points) {
  const std::size_t floats = 6 * points.size();
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(points.data());
  std::size_t i = 0;
#if defined(MARZIPAN_SPLATS_AVX2)
  if (useAvx2.load(std::memory_order_relaxed) && !allFiniteAvx2(bytes, floats, &i)) return false;
#endif
#if defined(MARZIPAN_SPLATS_SSE2)
  const __m128i exponent = _mm_set1_epi32(0x7f800000);
  __m128i bad = _mm_setzero_si128();
  for (; i + 4 <= floats; i += 4) {
    const __m128i w = _mm_loadu_si128(reinterpret_cast<const __m128i*>(bytes + 4 * i));
    bad = _mm_or_si128(bad, _mm_cmpeq_epi32(_mm_and_si128(w, exponent), exponent));
  }
  if (_mm_movemask_epi8(bad) != 0) return false;
#endif
  for (; i < floats; ++i) {
    float f;
    std::memcpy(&f, bytes + 4 * i, sizeof f);
    if (!std::isfinite(f)) return false;
  }
  return true;
}

// The checks of one brick (see encodeSplats).
void checkBrick(const BrickSplats& b) {
  for (int a = 0; a < 3; ++a)
    if (b.brick[a] < 0 || b.brick[a] > 0xffff)
      throw EngineError(ErrorKind::InvalidArgument, "brick", "coordinates must be in [0, 65535]");
  if (b.points.size() > std::size_t(kMaxPointsPerBrick))
    throw EngineError(ErrorKind::InvalidArgument, "points", "a brick holds at most 512 points");
  if (!b.texels.empty() && b.texels.size() != b.points.size())
    throw EngineError(ErrorKind::InvalidArgument, "texels", "a brick has no texels or one per point");
  if (!allFinite(b.points))
    throw EngineError(ErrorKind::InvalidArgument, "points", "positions and normals must be finite");
}

// Writes a checked brick's block at p; returns the byte after it.
std::uint8_t* writeBlock(const BrickSplats& b, std::uint8_t* p, std::uint16_t version) {
  const bool painted = paintedIn(b, version);
  put16(p, std::uint32_t(b.brick.x));
  put16(p + 2, std::uint32_t(b.brick.y));
  put16(p + 4, std::uint32_t(b.brick.z));
  put16(p + 6, std::uint32_t(b.points.size()) | (painted ? kSplatPaintedBit : 0));
  p += kSplatBrickHeaderBytes;
  const Int3 o{b.brick.x * kSplatBrickSide, b.brick.y * kSplatBrickSide, b.brick.z * kSplatBrickSide};
  // Point i's word at p + i * stride, its texel (painted) after the word. A group of eight (or
  // four) that encodePoints8 (encodePoints4) refuses, a normal too short to invert, leaves the
  // rest of the block to the narrower encoder after it, and at last to the one-point encoder:
  // all write the same bytes.
  const std::size_t stride = painted ? kSplatPaintedPointBytes : kSplatPointBytes, n = b.points.size();
  std::size_t i = 0;
#if defined(MARZIPAN_SPLATS_AVX2)
  if (useAvx2.load(std::memory_order_relaxed))
    for (; i + 8 <= n; i += 8)
      if (!encodePoints8(b.points.data() + i, o, p + i * stride, stride)) break;
#endif
#if defined(MARZIPAN_SPLATS_SSE2)
  for (; i + 4 <= n; i += 4)
    if (!encodePoints4(b.points.data() + i, o, p + i * stride, stride)) break;
#endif
  for (; i < n; ++i) put64(p + i * stride, encodePoint(b.points[i], o));
  if (painted)
    for (std::size_t k = 0; k < n; ++k) {
      const SplatTexel& t = b.texels[k];
      std::uint8_t* c = p + k * stride + kSplatPointBytes;
      c[0] = t.r, c[1] = t.g, c[2] = t.b, c[3] = t.mask;
    }
  return p + n * stride;
}

// The header of a buffer for blocks of the given brick keys holding `points` points in all, with
// room for `bytes` bytes in all (the blocks are appended, or written after a resize), after
// `headroom` bytes left unset; refuses a key listed twice.
std::vector<std::uint8_t> startBuffer(std::vector<std::uint64_t>& keys, std::size_t points, std::size_t bytes,
                                      std::uint16_t version, std::size_t headroom = 0) {
  std::sort(keys.begin(), keys.end());
  if (std::adjacent_find(keys.begin(), keys.end()) != keys.end())
    throw EngineError(ErrorKind::InvalidArgument, "brick", "a brick is listed twice");
  if (keys.size() > 0xffffffffu || points > 0xffffffffu)
    throw EngineError(ErrorKind::TooLarge, "splats", "more than 2^32 - 1 bricks or points");
  std::vector<std::uint8_t> out;
  out.reserve(headroom + bytes);
  out.resize(headroom + kSplatHeaderBytes);
  std::uint8_t* p = out.data() + headroom;
  std::memcpy(p, kMagic, 4);
  put16(p + 4, version);
  put16(p + 6, 0);
  put32(p + 8, std::uint32_t(keys.size()));
  put32(p + 12, std::uint32_t(points));
  return out;
}

// A block's header word N read in `version`: its point count and whether it is painted, or
// nothing when N is not one this version writes.
struct BlockCount {
  std::uint32_t n;
  bool painted;
  bool valid;
};
BlockCount readCount(std::uint32_t word, std::uint16_t version) {
  if (version == kSplatFormatVersionPlain) return {word, false, word <= std::uint32_t(kMaxPointsPerBrick)};
  const std::uint32_t n = word & kSplatCountMask;
  const bool painted = (word & kSplatPaintedBit) != 0;
  const bool valid = (word & ~(kSplatCountMask | kSplatPaintedBit)) == 0 &&
                     n <= std::uint32_t(kMaxPointsPerBrick) && (!painted || n > 0);
  return {n, painted, valid};
}

std::uint16_t readVersion(std::span<const std::uint8_t> bytes) {
  const std::size_t size = bytes.size();
  const std::uint8_t* p = bytes.data();
  if (size < kSplatHeaderBytes) formatError("truncated: " + std::to_string(size) + " bytes, the header alone takes 16");
  if (std::memcmp(p, kMagic, 4) != 0) formatError("not a splat buffer (wrong magic bytes)");
  const std::uint32_t version = get16(p + 4);
  if (version != kSplatFormatVersionPlain && version != kSplatFormatVersion)
    formatError("unsupported version " + std::to_string(version) + " (this build reads versions 1 and 2)");
  return std::uint16_t(version);
}

}  // namespace

bool splat_width::avx2Available() {
#if defined(MARZIPAN_SPLATS_AVX2)
  static const bool has = cpu::hasAvx2();
  return has;
#else
  return false;
#endif
}

void splat_width::allowAvx2([[maybe_unused]] bool allowed) {
#if defined(MARZIPAN_SPLATS_AVX2)
  useAvx2.store(allowed && avx2Available(), std::memory_order_relaxed);
#endif
}

std::vector<std::uint8_t> encodeSplats(const std::vector<BrickSplats>& bricks, std::uint16_t version) {
  checkVersion(version);
  std::vector<std::uint64_t> keys;
  keys.reserve(bricks.size());
  std::size_t points = 0;
  for (const auto& b : bricks) {
    checkBrick(b);
    keys.push_back(splatBrickKey(b.brick));
    points += b.points.size();
  }
  const std::size_t bytes = encodedSplatsSize(bricks, version);
  std::vector<std::uint8_t> out = startBuffer(keys, points, bytes, version);
  out.resize(bytes);
  std::uint8_t* p = out.data() + kSplatHeaderBytes;
  for (const auto& b : bricks) p = writeBlock(b, p, version);
  return out;
}

void encodeSplatBlock(const BrickSplats& brick, std::vector<std::uint8_t>& out, std::uint16_t version) {
  checkVersion(version);
  checkBrick(brick);
  out.resize(blockSize(brick, version));
  writeBlock(brick, out.data(), version);
}

std::vector<std::uint8_t> joinSplatBlocks(const std::vector<std::span<const std::uint8_t>>& blocks,
                                          std::uint16_t version, std::size_t headroom) {
  checkVersion(version);
  std::vector<std::uint64_t> keys;
  keys.reserve(blocks.size());
  std::size_t points = 0, bytes = kSplatHeaderBytes;
  for (const auto& b : blocks) {
    const BlockCount c = b.size() < kSplatBrickHeaderBytes ? BlockCount{0, false, false} : readCount(get16(b.data() + 6), version);
    if (!c.valid ||
        b.size() != kSplatBrickHeaderBytes + (c.painted ? kSplatPaintedPointBytes : kSplatPointBytes) * c.n)
      throw EngineError(ErrorKind::InvalidArgument, "blocks", "a block is not one brick's header and points");
    keys.push_back(splatBrickKey({int(get16(b.data())), int(get16(b.data() + 2)), int(get16(b.data() + 4))}));
    points += c.n;
    bytes += b.size();
  }
  std::vector<std::uint8_t> out = startBuffer(keys, points, bytes, version, headroom);
  for (const auto& b : blocks) out.insert(out.end(), b.begin(), b.end());
  return out;
}

std::vector<std::uint8_t> splatsAsVersion1(std::span<const std::uint8_t> bytes) {
  std::uint16_t version = 0;
  std::vector<BrickSplats> bricks = decodeSplats(bytes, &version);
  if (version == kSplatFormatVersionPlain) return {bytes.begin(), bytes.end()};
  // Decoded points are quantized already: they encode to the very codes they came from.
  return encodeSplats(bricks, kSplatFormatVersionPlain);
}

std::vector<BrickSplats> decodeSplats(std::span<const std::uint8_t> bytes, std::uint16_t* versionOut) {
  const std::uint16_t version = readVersion(bytes);
  const std::size_t size = bytes.size();
  const std::uint8_t* p = bytes.data();
  if (get16(p + 6) != 0) formatError("reserved header bytes must be 0");
  const std::uint32_t brickCount = get32(p + 8), pointCount = get32(p + 12);
  const std::size_t room = (size - kSplatHeaderBytes) / kSplatBrickHeaderBytes;
  if (brickCount > room || pointCount > room)
    formatError("counts (" + std::to_string(brickCount) + " bricks, " + std::to_string(pointCount) +
                " points) exceed what " + std::to_string(size) + " bytes can hold");

  std::vector<BrickSplats> out;
  out.reserve(brickCount);
  std::vector<std::uint64_t> keys;
  keys.reserve(brickCount);
  std::size_t at = kSplatHeaderBytes, points = 0;
  for (std::uint32_t i = 0; i < brickCount; ++i) {
    if (size - at < kSplatBrickHeaderBytes) formatError("truncated in the header of brick block " + std::to_string(i));
    const Int3 b{int(get16(p + at)), int(get16(p + at + 2)), int(get16(p + at + 4))};
    const std::uint32_t word = get16(p + at + 6);
    const BlockCount c = readCount(word, version);
    at += kSplatBrickHeaderBytes;
    if (!c.valid)
      formatError("brick block " + std::to_string(i) + " has N = " + std::to_string(word) +
                  (version == kSplatFormatVersionPlain
                       ? " (at most 512 points)"
                       : " (version 2: at most 512 points in bits 0..9, bits 10..14 zero, painted only with points)"));
    const std::size_t pointBytes = c.painted ? kSplatPaintedPointBytes : kSplatPointBytes;
    if ((size - at) / pointBytes < c.n) formatError("truncated in the points of brick block " + std::to_string(i));
    BrickSplats bs{b, {}, {}};
    bs.points.reserve(c.n);
    if (c.painted) bs.texels.reserve(c.n);
    const Int3 o{b.x * kSplatBrickSide, b.y * kSplatBrickSide, b.z * kSplatBrickSide};
    for (std::uint32_t k = 0; k < c.n; ++k, at += pointBytes) {
      bs.points.push_back(decodePoint(get64(p + at), o));
      if (c.painted) bs.texels.push_back({p[at + 8], p[at + 9], p[at + 10], p[at + 11]});
    }
    points += c.n;
    keys.push_back(splatBrickKey(b));
    out.push_back(std::move(bs));
  }
  if (at != size) formatError(std::to_string(size - at) + " trailing bytes after the last brick block");
  if (points != pointCount)
    formatError("the header announces " + std::to_string(pointCount) + " points, the blocks hold " +
                std::to_string(points));
  std::sort(keys.begin(), keys.end());
  if (std::adjacent_find(keys.begin(), keys.end()) != keys.end()) formatError("a brick is listed twice");
  if (versionOut) *versionOut = version;
  return out;
}

}  // namespace marzipan
