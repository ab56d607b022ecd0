// Splat extraction. Conventions: see splats.hpp.
//
// Speed: a brick that provably has no splat (one side of the surface and |d| >= kSurfaceNear
// throughout, neighbours' faces on the same side) is skipped after one counting pass. Others
// are copied once into a 10^3 array with a one-voxel ring (faces only: the splat of a voxel
// reads its six neighbours, never edge or corner neighbours); the test runs on 64-bit words,
// one per brick slice (the brick's inside and near bits, the ring's inside bits, shifted onto
// each other; a slice's bits from its floats in AVX2 where simd_width.hpp allows it, comparisons
// only, so the same bits), and only voxels whose bit survives are visited. Their splats
// are worked out four at a time in SSE2 (splats4), eight at a time in AVX2 where simd_width.hpp
// allows it (splats8), lane by lane the float operations of the scalar definition (splatAt,
// which MARZIPAN_SCALAR_KERNELS builds take) in its order.
#include "splats.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "simd_width.hpp"  // MARZIPAN_SSE2, MARZIPAN_AVX2
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "brick_table.hpp"
#include "errors.hpp"
#include "stencil.hpp"

namespace marzipan {

namespace {

constexpr int kPad = kBrickSide + 2;  // padded side: the brick and its ring
constexpr int kPadVoxels = kPad * kPad * kPad;
constexpr int kStride[3] = {1, kPad, kPad * kPad};

// Foot points are clamped to what the wire encoding can carry (protocol/cpp/values.hpp).
constexpr int kPosMax = kSplatPositionMax;
constexpr float kPosLow = kSplatPositionLow;
constexpr float kPosStep = kSplatPositionStep;
static_assert(kBrickSide == kSplatBrickSide, "splat buffers address bricks of 8^3 voxels");

// Index in the padded array of local voxel (x, y, z), each in [-1, kBrickSide].
constexpr int padIndex(int x, int y, int z) { return (x + 1) + kPad * ((y + 1) + kPad * (z + 1)); }


bool inGrid(const Volume& vol, Int3 b) {
  const Int3 n = vol.brickDims();
  return b.x >= 0 && b.y >= 0 && b.z >= 0 && b.x < n.x && b.y < n.y && b.z < n.z;
}

// Brick lookups for one extraction: straight from the volume (a few bricks), or from a
// BrickTable filled in one pass over the grid (a full extraction, which looks each brick up 7 times).
class BrickLookup {
 public:
  explicit BrickLookup(const Volume& vol) : vol_(vol), band_(vol.band()) {}

  void fillTable() { table_.emplace(vol_); }

  const Volume& volume() const { return vol_; }
  // The brick's voxels, or null with *u its uniform value; beyond the grid (by at most one
  // brick), null and +band.
  const float* operator()(Int3 b, float* u) const {
    if (table_) return table_->data(b, u);
    if (!inGrid(vol_, b)) {
      *u = band_;
      return nullptr;
    }
    return vol_.brickData(b, u);
  }
  // Outside also beyond the grid; table only.
  BrickTable::Kind kind(Int3 b) const { return table_->kind(b); }

 private:
  const Volume& vol_;
  float band_;
  std::optional<BrickTable> table_;
};

// Calls fn(k, value) for the kBrickSide^2 voxels of a brick's face (axis a, local coordinate c
// along it), with k = i + S j (S = kBrickSide) over the two other axes in increasing order.
// Loops follow memory.
template <class F>
void forFace(const float* v, int a, int c, F&& fn) {
  if (a == 0) {
    for (int r = 0; r < kBrickSide * kBrickSide; ++r) fn(r, v[c + kBrickSide * r]);  // k = y + S z
  } else if (a == 1) {
    for (int z = 0; z < kBrickSide; ++z)  // k = z + S x, visited x fastest
      for (int x = 0; x < kBrickSide; ++x) fn(z + kBrickSide * x, v[Bricks::index(x, c, z)]);
  } else {
    for (int r = 0; r < kBrickSide * kBrickSide; ++r) fn(r, v[kBrickSide * kBrickSide * c + r]);  // k = x + S y
  }
}

// True when some voxel of the neighbour's face next to us (the neighbour lies on side s of
// axis a) is on the other side of the surface than `inside`.
bool faceCrosses(const float* nd, int a, int s, bool inside) {
  int in = 0;
  forFace(nd, a, s < 0 ? kBrickSide - 1 : 0, [&](int, float v) { in += v < 0; });
  return in != (inside ? kBrickSide * kBrickSide : 0);
}

// A quick proof that the brick has no splat, which most bricks near a surface but not on it
// allow: no voxel has |d| < kSurfaceNear, all are on one side, and so is every voxel next to
// them (the neighbours' faces; air beyond the grid and past the domain's edge).
bool provablyEmpty(const BrickLookup& look, Int3 b, const float* own, float ownValue) {
  bool inside = ownValue < 0;
  if (own) {
    // Counts rather than a min/max: integer sums vectorize without fast-math. A slice at a
    // time: once some voxel is not far outside and some not far inside, the brick is not empty.
    int out = 0, in = 0;
    for (int slice = kBrickSide * kBrickSide; slice <= kBrickVoxels; slice += kBrickSide * kBrickSide) {
      for (int i = slice - kBrickSide * kBrickSide; i < slice; ++i) {
        out += own[i] >= kSurfaceNear;
        in += own[i] <= -kSurfaceNear;
      }
      if (out != slice && in != slice) return false;
    }
    if (out == kBrickVoxels) {
      inside = false;
    } else if (in == kBrickVoxels) {
      inside = true;
    } else {
      return false;
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (inside && (b[a] + 1) * kBrickSide > look.volume().dims()[a]) return false;
    for (int s = -1; s <= 1; s += 2) {
      Int3 nb = b;
      nb[a] += s;
      float u;
      const float* nd = look(nb, &u);
      if (nd ? faceCrosses(nd, a, s, inside) : ((u < 0) != inside)) return false;
    }
  }
  return true;
}

// Fills g with the brick's voxels and its six face rings; edges and corners of the ring are
// never read as neighbours of a brick voxel and only get a value (air) so that the byte tests
// below can run over the whole array.
void gatherPadded(const BrickLookup& look, Int3 b, const float* own, float ownValue, float* g) {
  const Volume& vol = look.volume();
  const float band = vol.band();
  // What the rows below leave unwritten: the ring's first and last slices, and its edges
  // along z (never read as a voxel's neighbours, but within the whole rows that are read).
  std::fill(g, g + kPad * kPad, band);
  std::fill(g + kPadVoxels - kPad * kPad, g + kPadVoxels, band);
  for (int z = 0; z < kBrickSide; ++z)
    for (const int y : {-1, kBrickSide})
      for (const int x : {-1, kBrickSide}) g[padIndex(x, y, z)] = band;
  for (int z = 0; z < kBrickSide; ++z)
    for (int y = 0; y < kBrickSide; ++y) {
      float* row = g + padIndex(0, y, z);
      if (own) {
        std::memcpy(row, own + Bricks::index(0, y, z), sizeof(float) * kBrickSide);
      } else {
        std::fill(row, row + kBrickSide, ownValue);
      }
    }
  // The ring voxel at padded coordinate -1 (or kBrickSide) along an axis is the neighbour's
  // last (or first) voxel along it. Written out per axis: constant strides, whole rows where
  // the face has them.
  for (int s = -1; s <= 1; s += 2) {
    const int ring = s < 0 ? -1 : kBrickSide, layer = s < 0 ? kBrickSide - 1 : 0;
    float u;
    if (const float* nd = look({b.x + s, b.y, b.z}, &u)) {
      for (int z = 0; z < kBrickSide; ++z)
        for (int y = 0; y < kBrickSide; ++y) g[padIndex(ring, y, z)] = nd[Bricks::index(layer, y, z)];
    } else {
      for (int z = 0; z < kBrickSide; ++z)
        for (int y = 0; y < kBrickSide; ++y) g[padIndex(ring, y, z)] = u;
    }
    if (const float* nd = look({b.x, b.y + s, b.z}, &u)) {
      for (int z = 0; z < kBrickSide; ++z)
        std::memcpy(g + padIndex(0, ring, z), nd + Bricks::index(0, layer, z), sizeof(float) * kBrickSide);
    } else {
      for (int z = 0; z < kBrickSide; ++z) std::fill(g + padIndex(0, ring, z), g + padIndex(kBrickSide, ring, z), u);
    }
    if (const float* nd = look({b.x, b.y, b.z + s}, &u)) {
      for (int y = 0; y < kBrickSide; ++y)
        std::memcpy(g + padIndex(0, y, ring), nd + Bricks::index(0, y, layer), sizeof(float) * kBrickSide);
    } else {
      for (int y = 0; y < kBrickSide; ++y) std::fill(g + padIndex(0, y, ring), g + padIndex(kBrickSide, y, ring), u);
    }
  }
  // Voxels past the domain's far edge read as air, whatever the brick stores there.
  const Int3 o = Bricks::origin(b);
  const Int3 dims = vol.dims();
  if (o.x + kBrickSide + 1 > dims.x || o.y + kBrickSide + 1 > dims.y || o.z + kBrickSide + 1 > dims.z) {
    for (int z = -1; z <= kBrickSide; ++z)
      for (int y = -1; y <= kBrickSide; ++y)
        for (int x = -1; x <= kBrickSide; ++x)
          if (o.x + x >= dims.x || o.y + y >= dims.y || o.z + z >= dims.z) g[padIndex(x, y, z)] = band;
  }
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

static_assert(kBrickSide == 8, "a brick slice is one 64-bit word");
constexpr std::uint64_t kColumn0 = 0x0101010101010101ull, kColumn7 = kColumn0 << 7, kRow0 = 0xffull,
                        kRow7 = kRow0 << 56;

// Bit x + 8 y of domain[z]: voxel (x, y, z) of brick b lies in the domain.
void domainSlices(const Volume& vol, Int3 b, std::uint64_t domain[kBrickSide]) {
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
__attribute__((target("avx2"))) void sliceBitsAvx2(const float* v, std::uint64_t& inside, std::uint64_t& near) {
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
void sliceBits(const float* v, std::uint64_t& inside, std::uint64_t& near) {
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
void brickSliceBits(const float* data, float uniform, int z, std::uint64_t domain, std::uint64_t& inside,
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
std::uint32_t rowInside(const float* v) {
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
std::uint64_t columnInside(const float* v, int stride) {
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

// The encodable range of foot points along an axis of a brick with origin coordinate `origin`.
float positionLow(float origin) { return origin + kPosLow; }
float positionHigh(float origin) { return origin + kPosLow + kPosStep * float(kPosMax); }

#if !defined(MARZIPAN_SSE2)
float clampPosition(float q, float origin) { return std::clamp(q, positionLow(origin), positionHigh(origin)); }

// The splat of the surface voxel at padded index c of g, voxel (px, py, pz) of the brick with
// origin o.
Splat splatAt(const float* g, int c, Int3 p, Int3 o) {
  const float d = g[c];
  // Twice the gradient: only its direction is kept.
  const GradStencil st = GradStencil::inArray(g + c, kStride[0], kStride[1], kStride[2]);
  const float gx = st.difference(0), gy = st.difference(1), gz = st.difference(2);
  const float len2 = gx * gx + gy * gy + gz * gz;
  const float px = float(p.x), py = float(p.y), pz = float(p.z);
  Splat sp{px, py, pz, 0, 0, 1};
  if (len2 > 0) {
    const float inv = 1 / std::sqrt(len2);
    sp.nx = gx * inv;
    sp.ny = gy * inv;
    sp.nz = gz * inv;
    sp.x = clampPosition(px - d * sp.nx, float(o.x));
    sp.y = clampPosition(py - d * sp.ny, float(o.y));
    sp.z = clampPosition(pz - d * sp.nz, float(o.z));
  }
  return sp;
}
#else
// Four splats from their six fields (x, y, z, nx, ny, nz, a lane each) into out[0..4): back to
// six floats per splat, rows (x0 y0 z0 nx0), (ny0 nz0 x1 y1), (z1 nx1 ny1 nz1), ...
void storeSplats4(const __m128 f[6], Splat* out) {
  const __m128 xyLo = _mm_unpacklo_ps(f[0], f[1]), xyHi = _mm_unpackhi_ps(f[0], f[1]);
  const __m128 znLo = _mm_unpacklo_ps(f[2], f[3]), znHi = _mm_unpackhi_ps(f[2], f[3]);
  const __m128 nnLo = _mm_unpacklo_ps(f[4], f[5]), nnHi = _mm_unpackhi_ps(f[4], f[5]);
  static_assert(sizeof(Splat) == 6 * sizeof(float), "a splat is six packed floats");
  float* w = reinterpret_cast<float*>(out);
  _mm_storeu_ps(w, _mm_movelh_ps(xyLo, znLo));
  _mm_storeu_ps(w + 4, _mm_shuffle_ps(nnLo, xyLo, _MM_SHUFFLE(3, 2, 1, 0)));
  _mm_storeu_ps(w + 8, _mm_movehl_ps(nnLo, znLo));
  _mm_storeu_ps(w + 12, _mm_movelh_ps(xyHi, znHi));
  _mm_storeu_ps(w + 16, _mm_shuffle_ps(nnHi, xyHi, _MM_SHUFFLE(3, 2, 1, 0)));
  _mm_storeu_ps(w + 20, _mm_movehl_ps(nnHi, znHi));
}

// splatAt for the four surface voxels voxel[0..4) (Bricks::index) of the brick with origin o,
// g its padded array, into out[0..4): lane by lane the same float operations in the same order.
// std::clamp(q, lo, hi) is max(lo, q) then min(hi, ...) in that operand order, which keeps a NaN
// as clamp does.
void splats4(const float* g, const std::int32_t* voxel, Int3 o, Splat* out) {
  // Each lane's local coordinates, its voxel's coordinates and its padded index
  // padIndex(x, y, z) = padIndex(0, 0, 0) + x + kPad y + kPad^2 z (10 y = 8 y + 2 y, 100 z =
  // 64 z + 32 z + 4 z: SSE2 has no 32-bit multiply).
  static_assert(kBrickSide == 8 && kPad == 10, "the shifts below");
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(voxel)), seven = _mm_set1_epi32(7);
  const __m128i lx = _mm_and_si128(v, seven), ly = _mm_and_si128(_mm_srli_epi32(v, 3), seven), lz = _mm_srli_epi32(v, 6);
  const __m128i padded = _mm_add_epi32(
      _mm_add_epi32(_mm_set1_epi32(padIndex(0, 0, 0)), lx),
      _mm_add_epi32(_mm_add_epi32(_mm_slli_epi32(ly, 3), _mm_slli_epi32(ly, 1)),
                    _mm_add_epi32(_mm_add_epi32(_mm_slli_epi32(lz, 6), _mm_slli_epi32(lz, 5)), _mm_slli_epi32(lz, 2))));
  alignas(16) std::int32_t cell[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(cell), padded);
  const __m128i at[3] = {_mm_add_epi32(lx, _mm_set1_epi32(o.x)), _mm_add_epi32(ly, _mm_set1_epi32(o.y)),
                         _mm_add_epi32(lz, _mm_set1_epi32(o.z))};
  // Each voxel's row g[c - 1 .. c + 2], transposed: its x neighbours and its value per lane.
  __m128 r0 = _mm_loadu_ps(g + cell[0] - 1), r1 = _mm_loadu_ps(g + cell[1] - 1), r2 = _mm_loadu_ps(g + cell[2] - 1),
         r3 = _mm_loadu_ps(g + cell[3] - 1);
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  const auto lanes = [&](int offset) {
    return _mm_set_ps(g[cell[3] + offset], g[cell[2] + offset], g[cell[1] + offset], g[cell[0] + offset]);
  };
  const __m128 d = r1;
  const __m128 gx = _mm_sub_ps(r2, r0), gy = _mm_sub_ps(lanes(kStride[1]), lanes(-kStride[1])),
               gz = _mm_sub_ps(lanes(kStride[2]), lanes(-kStride[2]));
  const __m128 len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(gx, gx), _mm_mul_ps(gy, gy)), _mm_mul_ps(gz, gz));
  const __m128 some = _mm_cmpgt_ps(len2, _mm_setzero_ps());
  const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), _mm_sqrt_ps(len2));
  const __m128 n[3] = {_mm_mul_ps(gx, inv), _mm_mul_ps(gy, inv), _mm_mul_ps(gz, inv)};
  const float origin[3] = {float(o.x), float(o.y), float(o.z)};
  const float fallbackNormal[3] = {0, 0, 1};
  __m128 f[6];  // x, y, z, nx, ny, nz per lane
  for (int a = 0; a < 3; ++a) {
    const __m128 p = _mm_cvtepi32_ps(at[a]);
    const __m128 q = _mm_sub_ps(p, _mm_mul_ps(d, n[a]));
    const __m128 foot = _mm_min_ps(_mm_set1_ps(positionHigh(origin[a])), _mm_max_ps(_mm_set1_ps(positionLow(origin[a])), q));
    f[a] = _mm_or_ps(_mm_and_ps(some, foot), _mm_andnot_ps(some, p));
    f[3 + a] = _mm_or_ps(_mm_and_ps(some, n[a]), _mm_andnot_ps(some, _mm_set1_ps(fallbackNormal[a])));
  }
  storeSplats4(f, out);
}
#endif

#if defined(MARZIPAN_AVX2)
// splats4 for the eight surface voxels voxel[0..8) into out[0..8): each lane's value and six
// neighbours gathered from g (one instruction a field, where splats4 transposes rows and sets
// lanes one by one), then the same float operations in the same order on eight lanes, and the
// two halves written back as splats4 writes its four (storeSplats4).
__attribute__((target("avx2"))) void splats8(const float* g, const std::int32_t* voxel, Int3 o, Splat* out) {
  static_assert(kBrickSide == 8 && kPad == 10, "the shifts below");
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(voxel)), seven = _mm256_set1_epi32(7);
  const __m256i lx = _mm256_and_si256(v, seven), ly = _mm256_and_si256(_mm256_srli_epi32(v, 3), seven),
                lz = _mm256_srli_epi32(v, 6);
  const __m256i cell = _mm256_add_epi32(
      _mm256_add_epi32(_mm256_set1_epi32(padIndex(0, 0, 0)), lx),
      _mm256_add_epi32(_mm256_mullo_epi32(ly, _mm256_set1_epi32(kPad)), _mm256_mullo_epi32(lz, _mm256_set1_epi32(kPad * kPad))));
  const __m256 d = _mm256_i32gather_ps(g, cell, 4);
  // The reads below a voxel index from cell - kPad * kPad, so that every base pointer lies within
  // g's array (g - stride would point before it).
  const __m256i below = _mm256_sub_epi32(cell, _mm256_set1_epi32(kStride[2]));
  const __m256 gx = _mm256_sub_ps(_mm256_i32gather_ps(g + kStride[0], cell, 4),
                                  _mm256_i32gather_ps(g + kStride[2] - kStride[0], below, 4));
  const __m256 gy = _mm256_sub_ps(_mm256_i32gather_ps(g + kStride[1], cell, 4),
                                  _mm256_i32gather_ps(g + kStride[2] - kStride[1], below, 4));
  const __m256 gz = _mm256_sub_ps(_mm256_i32gather_ps(g + kStride[2], cell, 4), _mm256_i32gather_ps(g, below, 4));
  const __m256 len2 =
      _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(gx, gx), _mm256_mul_ps(gy, gy)), _mm256_mul_ps(gz, gz));
  const __m256 some = _mm256_cmp_ps(len2, _mm256_setzero_ps(), _CMP_GT_OQ);
  const __m256 inv = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_sqrt_ps(len2));
  const __m256 n[3] = {_mm256_mul_ps(gx, inv), _mm256_mul_ps(gy, inv), _mm256_mul_ps(gz, inv)};
  const __m256i local[3] = {lx, ly, lz};
  const int origin[3] = {o.x, o.y, o.z};
  const float fallbackNormal[3] = {0, 0, 1};
  __m256 f[6];  // x, y, z, nx, ny, nz per lane
  for (int a = 0; a < 3; ++a) {
    const __m256 p = _mm256_cvtepi32_ps(_mm256_add_epi32(local[a], _mm256_set1_epi32(origin[a])));
    const __m256 q = _mm256_sub_ps(p, _mm256_mul_ps(d, n[a]));
    const __m256 foot = _mm256_min_ps(_mm256_set1_ps(positionHigh(float(origin[a]))),
                                      _mm256_max_ps(_mm256_set1_ps(positionLow(float(origin[a]))), q));
    f[a] = _mm256_blendv_ps(p, foot, some);
    f[3 + a] = _mm256_blendv_ps(_mm256_set1_ps(fallbackNormal[a]), n[a], some);
  }
  __m128 low[6], high[6];
  for (int k = 0; k < 6; ++k) {
    low[k] = _mm256_castps256_ps128(f[k]);
    high[k] = _mm256_extractf128_ps(f[k], 1);
  }
  storeSplats4(low, out);
  storeSplats4(high, out + 4);
}
#endif

void checkBrick(const Volume& vol, Int3 b) {
  if (!inGrid(vol, b)) {
    const Int3 n = vol.brickDims();
    std::ostringstream s;
    s << "brick (" << b.x << ", " << b.y << ", " << b.z << ") is outside the brick grid " << n.x << "x" << n.y << "x"
      << n.z;
    throw EngineError(ErrorKind::OutOfDomain, "brick", s.str());
  }
}

BrickSplats extractWith(const BrickLookup& look, Int3 b) {
  const Volume& vol = look.volume();
  BrickSplats out{b, {}};
  float ownValue;
  const float* own = look(b, &ownValue);
  if (provablyEmpty(look, b, own, ownValue)) return out;

  float g[kPadVoxels];
  gatherPadded(look, b, own, ownValue, g);

  // The test on 64-bit words, bit x + 8 y of slice z (as bricksAroundChanges): d < 0 and
  // |d| < kSurfaceNear of the brick's voxels in the domain, d < 0 of the ring's (from g, which
  // reads past the domain as +band); a voxel is next to the surface when near or when a face
  // neighbour's inside bit differs. Then its splat, in voxel order.
  const Int3 o = Bricks::origin(b);
  const int zs = std::min(kBrickSide, vol.dims().z - o.z);
  std::uint64_t in[kBrickSide + 2], nearBits[kBrickSide], domain[kBrickSide];  // in: slices -1 .. kBrickSide
  domainSlices(vol, b, domain);
  for (int z = 0; z < kBrickSide; ++z) brickSliceBits(own, ownValue, z, domain[z], in[z + 1], nearBits[z]);
  for (const int z : {-1, kBrickSide}) {
    std::uint64_t slice = 0;
    for (int y = 0; y < kBrickSide; ++y) slice |= std::uint64_t(rowInside(g + padIndex(0, y, z))) << (kBrickSide * y);
    in[z + 1] = slice;
  }

  // The surface voxels first (Bricks::index), then their splats. A last group of eight, filled
  // up with copies, still fits: at most every voxel is a surface voxel, a whole number of eights.
  constexpr int kRoom = kBrickVoxels;
  static_assert(kRoom % 8 == 0);
  std::int32_t voxel[kRoom];
  int count = 0;
  static_assert(Bricks::index(0, 0, 1) == kBrickSide * kBrickSide, "bit x + 8 y of slice z is voxel bit + 64 z");
  for (int z = 0; z < zs; ++z) {
    const std::uint64_t xLow = columnInside(g + padIndex(-1, 0, z), kPad),
                        xHigh = columnInside(g + padIndex(kBrickSide, 0, z), kPad) << (kBrickSide - 1);
    const std::uint64_t yLow = rowInside(g + padIndex(0, -1, z)),
                        yHigh = std::uint64_t(rowInside(g + padIndex(0, kBrickSide, z))) << (kBrickSide * (kBrickSide - 1));
    const std::uint64_t c = in[z + 1];
    const std::uint64_t surface = nearBits[z] | (c ^ (((c << 1) & ~kColumn0) | xLow)) |
                                  (c ^ (((c >> 1) & ~kColumn7) | xHigh)) | (c ^ ((c << kBrickSide) | yLow)) |
                                  (c ^ ((c >> kBrickSide) | yHigh)) | (c ^ in[z]) | (c ^ in[z + 2]);
    const int slice = Bricks::index(0, 0, z);
    for (std::uint64_t m = surface & domain[z]; m; m &= m - 1) voxel[count++] = slice + std::countr_zero(m);
  }
  Splat found[kRoom];
#if defined(MARZIPAN_SSE2)
  // The last group filled up with its first voxel.
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) {
    for (int i = count; i % 8 != 0; ++i) voxel[i] = voxel[i & ~7];
    for (int i = 0; i < count; i += 8) splats8(g, voxel + i, o, found + i);
  } else
#endif
  {
    for (int i = count; i % 4 != 0; ++i) voxel[i] = voxel[i & ~3];
    for (int i = 0; i < count; i += 4) splats4(g, voxel + i, o, found + i);
  }
#else
  for (int i = 0; i < count; ++i) {
    const int x = voxel[i] % kBrickSide, y = voxel[i] / kBrickSide % kBrickSide, z = voxel[i] / (kBrickSide * kBrickSide);
    found[i] = splatAt(g, padIndex(x, y, z), {o.x + x, o.y + y, o.z + z}, o);
  }
#endif
  out.points.assign(found, found + count);
  // The voxels of a brick without channels all read the base colour, weight 0: its points take
  // the session's base colour on the client, and carry nothing.
  if (const BrickPaint* paint = own && count > 0 ? vol.brickPaint(b) : nullptr) {
    out.texels.resize(std::size_t(count));
    for (int i = 0; i < count; ++i) {
      const Texel& t = paint->t[voxel[i]];
      out.texels[std::size_t(i)] = {t.r, t.g, t.b, t.mask};
    }
  }
  return out;
}

std::vector<BrickSplats> extractAll(const BrickLookup& look, const std::vector<Int3>& bricks, ThreadPool& pool) {
  std::vector<BrickSplats> out(bricks.size());
  pool.parallelFor(bricks.size(), [&](std::size_t i) { out[i] = extractWith(look, bricks[i]); });
  return out;
}

}  // namespace

BrickSplats extractBrickSplats(const Volume& vol, Int3 b) {
  checkBrick(vol, b);
  return extractWith(BrickLookup(vol), b);
}

std::vector<BrickSplats> extractSplats(const Volume& vol, const std::vector<Int3>& bricks, ThreadPool& pool) {
  for (const Int3& b : bricks) checkBrick(vol, b);
  return extractAll(BrickLookup(vol), bricks, pool);
}

std::vector<BrickSplats> extractAllSplats(const Volume& vol, ThreadPool& pool) {
  // Candidates: stored bricks, and uniform bricks next to a brick of another kind (or, for
  // inside bricks, next to the domain's edge). Others hold no sign change and no |d| < band.
  BrickLookup look(vol);
  look.fillTable();
  const Int3 n = vol.brickDims();
  std::vector<Int3> candidates;
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const Int3 b{x, y, z};
        const BrickTable::Kind k = look.kind(b);
        bool keep = k == BrickTable::Kind::Stored;
        for (int a = 0; a < 3 && !keep; ++a) {
          keep = k == BrickTable::Kind::Inside && (b[a] + 1) * kBrickSide > vol.dims()[a];
          for (int s = -1; s <= 1 && !keep; s += 2) {
            Int3 nb = b;
            nb[a] += s;
            keep = look.kind(nb) != k;
          }
        }
        if (keep) candidates.push_back(b);
      }

  auto all = extractAll(look, candidates, pool);
  std::erase_if(all, [](const BrickSplats& bs) { return bs.points.empty(); });
  return all;
}

namespace {

bool zyxLess(Int3 a, Int3 b) { return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x); }

// Brick b's index in a grid of n bricks, x fastest: in-grid bricks sort z, y, x as their indices.
std::uint64_t gridIndex(Int3 n, Int3 b) {
  return std::uint64_t(b.x) + std::uint64_t(n.x) * (std::uint64_t(b.y) + std::uint64_t(n.y) * std::uint64_t(b.z));
}

// The bricks of the grid indices `at`, sorted z, y, x and without duplicates (at is sorted).
std::vector<Int3> sortedBricks(Int3 n, std::vector<std::uint64_t>& at) {
  std::sort(at.begin(), at.end());
  at.erase(std::unique(at.begin(), at.end()), at.end());
  std::vector<Int3> out;
  out.reserve(at.size());
  for (const std::uint64_t i : at) {
    const std::uint64_t row = i / std::uint64_t(n.x);
    out.push_back({int(i % std::uint64_t(n.x)), int(row % std::uint64_t(n.y)), int(row / std::uint64_t(n.y))});
  }
  return out;
}

// What bricksAroundChanges reads of a brick in the two states (0: before the changes, 1: after),
// worked out slice by slice as needed: bit x + 8 y of word z of `inside` is d < 0, of `near`
// |d| < kSurfaceNear, of `diff` that the value differs bit for bit between the states. Voxels
// past the domain's far edge read as extraction reads them, +band: outside, not near, the same
// in both states. A brick the changes leave alone has one state (same).
struct BrickBits {
  BrickBits() = default;
  // Made in place in StateBits' table, the words left as they are until worked out.
  explicit BrickBits(Int3 b) : brick(b) {}

  Int3 brick;
  const BrickChange* change;  // null: unchanged
  const float* data[2];
  float u[2];
  bool same = true;
  unsigned ready[2] = {0, 0};  // slices of inside and near worked out
  std::uint64_t inside[2][kBrickSide], near[2][kBrickSide], diff[kBrickSide];
  std::uint64_t domain[kBrickSide];  // domainSlices
};
#if defined(MARZIPAN_AVX2)
// sliceDiff thirty-two words at a time, a null side compared as its value broadcast: the
// comparisons' lanes narrowed by packs and put back in order as sliceBitsAvx2 does.
__attribute__((target("avx2"))) std::uint64_t sliceDiffAvx2(const float* a, float ua, const float* b, float ub) {
  const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
  const __m256i wa = _mm256_castps_si256(_mm256_set1_ps(ua)), wb = _mm256_castps_si256(_mm256_set1_ps(ub));
  std::uint64_t same = 0;
  for (int i = 0; i < kBrickSide * kBrickSide; i += 32) {
    __m256i e[4];
    for (int k = 0; k < 4; ++k) {
      const __m256i x = a ? _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a + i + 8 * k)) : wa;
      const __m256i y = b ? _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + i + 8 * k)) : wb;
      e[k] = _mm256_cmpeq_epi32(x, y);
    }
    const __m256i bytes = _mm256_permutevar8x32_epi32(
        _mm256_packs_epi16(_mm256_packs_epi32(e[0], e[1]), _mm256_packs_epi32(e[2], e[3])), order);
    same |= std::uint64_t(std::uint32_t(_mm256_movemask_epi8(bytes))) << i;
  }
  return ~same;
}
#endif

// The bits of slice z whose value differs bit for bit between a and b (either may be null: the
// uniform value ua or ub throughout).
std::uint64_t sliceDiff(const float* a, float ua, const float* b, float ub) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return sliceDiffAvx2(a, ua, b, ub);
#endif
  float fa[kBrickSide * kBrickSide], fb[kBrickSide * kBrickSide];
  if (!a) std::fill(fa, fa + kBrickSide * kBrickSide, ua), a = fa;
  if (!b) std::fill(fb, fb + kBrickSide * kBrickSide, ub), b = fb;
  std::uint64_t m = 0;
#if defined(MARZIPAN_SSE2)
  for (int i = 0; i < kBrickSide * kBrickSide; i += 16) {
    __m128i e[4];
    for (int k = 0; k < 4; ++k)
      e[k] = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i + 4 * k)),
                             _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i + 4 * k)));
    const __m128i same = _mm_packs_epi16(_mm_packs_epi32(e[0], e[1]), _mm_packs_epi32(e[2], e[3]));
    m |= std::uint64_t(~std::uint32_t(_mm_movemask_epi8(same)) & 0xffffu) << i;
  }
#else
  for (int i = 0; i < kBrickSide * kBrickSide; ++i)
    m |= std::uint64_t(std::bit_cast<std::uint32_t>(a[i]) != std::bit_cast<std::uint32_t>(b[i])) << i;
#endif
  return m;
}

// BrickBits of the bricks bricksAroundChanges reads, made when first asked for, the changed
// ones (sorted z, y, x) first; found by hashing their index in the grid.
class StateBits {
 public:
  StateBits(const Volume& vol, const std::vector<const BrickChange*>& sorted) : vol_(vol) {
    BrickBits air{};
    air.change = nullptr;
    air.brick = {-1, -1, -1};
    air.u[0] = air.u[1] = vol.band();
    air.ready[0] = air.ready[1] = 0xffu;
    bits_.reserve(4 * sorted.size() + 1);
    bits_.push_back(air);
    slots_.assign(std::bit_ceil(std::max<std::size_t>(64, 16 * sorted.size())), -1);
    for (const BrickChange* c : sorted) of(c->brick, c);
  }

  const Volume& volume() const { return vol_; }
  // The changed bricks' bits, in the order of `sorted`.
  const BrickBits& changed(std::size_t i) const { return bits_[1 + i]; }
  // Valid until the next of() that makes a brick's bits.
  BrickBits& at(std::size_t i) { return bits_[i]; }

  // An index for at(); beyond the grid, air: +band, all bits 0. Bricks the constructor did not
  // make are unchanged.
  std::size_t of(Int3 b, const BrickChange* change = nullptr) {
    if (!inGrid(vol_, b)) return 0;
    for (std::size_t h = slot(b);; h = (h + 1) & (slots_.size() - 1)) {
      if (slots_[h] < 0) {
        make(bits_.emplace_back(b), change);
        slots_[h] = std::int64_t(bits_.size() - 1);
        if (2 * bits_.size() > slots_.size()) grow();
        return bits_.size() - 1;
      }
      if (bits_[std::size_t(slots_[h])].brick == b) return std::size_t(slots_[h]);
    }
  }

  std::uint64_t inside(BrickBits& x, int s, int z) const {
    s = x.same ? 0 : s;
    if (!(x.ready[s] >> z & 1)) work(x, s, z);
    return x.inside[s][z];
  }
  // Only the bits of `part` of inside(x, s, z): a column (kColumn0 or kColumn7) or a row (kRow0
  // or kRow7), read alone when the slice is not worked out.
  std::uint64_t insidePart(BrickBits& x, int s, int z, std::uint64_t part) const {
    s = x.same ? 0 : s;
    if (x.ready[s] >> z & 1) return x.inside[s][z] & part;
    std::uint64_t m = 0;
    if (!x.data[s]) {
      m = x.u[s] < 0 ? part : 0;
    } else if (part == kRow0 || part == kRow7) {
      const int y = part == kRow0 ? 0 : kBrickSide - 1;
      m = std::uint64_t(rowInside(x.data[s] + Bricks::index(0, y, z))) << (kBrickSide * y);
    } else {
      const int c = part == kColumn0 ? 0 : kBrickSide - 1;
      m = columnInside(x.data[s] + Bricks::index(c, 0, z), kBrickSide) << c;
    }
    return m & x.domain[z];
  }
  std::uint64_t near(BrickBits& x, int s, int z) const {
    s = x.same ? 0 : s;
    if (!(x.ready[s] >> z & 1)) work(x, s, z);
    return x.near[s][z];
  }

 private:
  void make(BrickBits& x, const BrickChange* c) const {
    const Int3 b = x.brick;
    domainSlices(vol_, b, x.domain);
    const float band = vol_.band();
    x.change = c;
    if (c) {
      x.data[0] = c->before.data ? c->before.data->v : nullptr;
      x.data[1] = c->after.data ? c->after.data->v : nullptr;
      x.u[0] = c->before.inside ? -band : band;
      x.u[1] = c->after.inside ? -band : band;
      x.same = x.data[0] == x.data[1] && (x.data[0] || x.u[0] == x.u[1]);
    } else {
      x.data[0] = x.data[1] = vol_.brickData(b, &x.u[0]);
      x.u[1] = x.u[0];
    }
    for (int z = 0; z < kBrickSide; ++z) {
      const int at = Bricks::index(0, 0, z);
      if (x.same) {
        x.diff[z] = 0;
      } else {
        x.diff[z] = x.domain[z] & sliceDiff(x.data[0] ? x.data[0] + at : nullptr, x.u[0],
                                                        x.data[1] ? x.data[1] + at : nullptr, x.u[1]);
      }
    }
  }
  void work(BrickBits& x, int s, int z) const {
    brickSliceBits(x.data[s], x.u[s], z, x.domain[z], x.inside[s][z], x.near[s][z]);
    x.ready[s] |= 1u << z;
  }

  // Where the probe for brick b starts: its index in the grid, hashed (Fibonacci).
  std::size_t slot(Int3 b) const {
    return std::size_t((gridIndex(vol_.brickDims(), b) * 0x9e3779b97f4a7c15ull) >> 24) & (slots_.size() - 1);
  }
  void grow() {
    slots_.assign(2 * slots_.size(), -1);
    for (std::size_t i = 1; i < bits_.size(); ++i) {
      std::size_t h = slot(bits_[i].brick);
      while (slots_[h] >= 0) h = (h + 1) & (slots_.size() - 1);
      slots_[h] = std::int64_t(i);
    }
  }

  const Volume& vol_;
  std::vector<BrickBits> bits_;  // air first
  std::vector<std::int64_t> slots_;  // indices into bits_, -1 free; at most half used
};

// The voxels of slice z of brick `own` with a 6-neighbour that differs between the states (n: the
// neighbours on the low and high side of x, y, z). Shifting a slice's word by 1 or 8 moves each
// bit to the voxel next to it along x or y; the bits that cross a row or the slice's edge are
// the neighbour brick's face.
std::uint64_t diffNextTo(const BrickBits& own, const BrickBits* const n[6], int z) {
  const std::uint64_t s = own.diff[z];
  return ((s << 1) & ~kColumn0) | ((n[0]->diff[z] & kColumn7) >> 7) | ((s >> 1) & ~kColumn7) |
         ((n[1]->diff[z] & kColumn0) << 7) | (s << 8) | (n[2]->diff[z] >> 56) | (s >> 8) |
         (n[3]->diff[z] << 56) | (z > 0 ? own.diff[z - 1] : n[4]->diff[kBrickSide - 1]) |
         (z < kBrickSide - 1 ? own.diff[z + 1] : n[5]->diff[0]);
}

constexpr Int3 kSix[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};

// Whether brick b's block is provably the same in the two states: the splat of voxel p reads
// d(p), its six neighbours (as extraction reads them: past the domain, +band) and p's texel, so
// it is unchanged unless one of those seven values changed bit for bit and p is next to the
// surface in one of the states; and the texels are unchanged when the brick keeps its channels'
// buffer (another buffer, even with the same texels, keeps the brick: paint strokes change
// them anyway).
bool sameSplats(StateBits& bits, Int3 b) {
  std::size_t index[7] = {bits.of(b)};
  for (int i = 0; i < 6; ++i) index[i + 1] = bits.of(b + kSix[i]);
  BrickBits& own = bits.at(index[0]);
  if (own.change && own.change->before.paint != own.change->after.paint) return false;
  BrickBits* n[6];
  for (int i = 0; i < 6; ++i) n[i] = &bits.at(index[i + 1]);
  std::uint64_t nb[6];
  for (int z = 0; z < kBrickSide; ++z) {
    // Affected: the voxel or a neighbour differs (past the domain, nothing differs).
    const std::uint64_t affected = (own.diff[z] | diffNextTo(own, n, z)) & own.domain[z];
    if (!affected) continue;
    // One of them next to the surface in either state decides.
    for (int s = 0; s < 2; ++s) {
      const std::uint64_t in = bits.inside(own, s, z);
      // The same shifts as diffNextTo; a neighbour brick's face read only where an affected
      // voxel lies next to it.
      nb[0] = ((in << 1) & ~kColumn0) | (affected & kColumn0 ? bits.insidePart(*n[0], s, z, kColumn7) >> 7 : 0);
      nb[1] = ((in >> 1) & ~kColumn7) | (affected & kColumn7 ? bits.insidePart(*n[1], s, z, kColumn0) << 7 : 0);
      nb[2] = (in << 8) | (affected & kRow0 ? bits.insidePart(*n[2], s, z, kRow7) >> 56 : 0);
      nb[3] = (in >> 8) | (affected & kRow7 ? bits.insidePart(*n[3], s, z, kRow0) << 56 : 0);
      nb[4] = z > 0 ? bits.inside(own, s, z - 1) : bits.inside(*n[4], s, kBrickSide - 1);
      nb[5] = z < kBrickSide - 1 ? bits.inside(own, s, z + 1) : bits.inside(*n[5], s, 0);
      const std::uint64_t surface = bits.near(own, s, z) | (in ^ nb[0]) | (in ^ nb[1]) | (in ^ nb[2]) |
                                    (in ^ nb[3]) | (in ^ nb[4]) | (in ^ nb[5]);
      if (affected & surface) return false;
    }
  }
  return true;
}

}  // namespace

std::vector<Int3> bricksAroundChanges(const Volume& vol, const std::vector<BrickChange>& changes) {
  std::vector<const BrickChange*> sorted;
  for (const auto& c : changes)
    if (inGrid(vol, c.brick)) sorted.push_back(&c);
  std::sort(sorted.begin(), sorted.end(),
            [](const BrickChange* a, const BrickChange* b) { return zyxLess(a->brick, b->brick); });
  const Int3 n = vol.brickDims();
  std::vector<std::uint64_t> listed;  // grid indices
  listed.reserve(sorted.size() * 7);
  // A brick changed twice in one list has no one state to compare: every changed brick and
  // every face neighbour stays.
  for (std::size_t i = 1; i < sorted.size(); ++i)
    if (sorted[i - 1]->brick == sorted[i]->brick) {
      for (const BrickChange* c : sorted)
        for (int j = -1; j < 6; ++j) {
          const Int3 nb = j < 0 ? c->brick : c->brick + kSix[j];
          if (inGrid(vol, nb)) listed.push_back(gridIndex(n, nb));
        }
      return sortedBricks(n, listed);
    }
  // The changed bricks and those face neighbours whose layer of them next to them differs:
  // no other brick reads a changed value.
  StateBits bits(vol, sorted);
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    const BrickBits& c = bits.changed(i);
    listed.push_back(gridIndex(n, c.brick));
    const std::uint64_t* d = c.diff;
    std::uint64_t all = 0;
    for (int z = 0; z < kBrickSide; ++z) all |= d[z];
    const bool layer[6] = {(all & kColumn0) != 0, (all & kColumn7) != 0, (all & kRow0) != 0,
                           (all & kRow7) != 0,    d[0] != 0,              d[kBrickSide - 1] != 0};
    for (int k = 0; k < 6; ++k)
      if (layer[k] && inGrid(vol, c.brick + kSix[k])) listed.push_back(gridIndex(n, c.brick + kSix[k]));
  }
  std::vector<Int3> out = sortedBricks(n, listed);
  // Of those, the bricks whose blocks provably come out the same are left out.
  std::erase_if(out, [&](Int3 b) { return sameSplats(bits, b); });
  return out;
}

}  // namespace marzipan
