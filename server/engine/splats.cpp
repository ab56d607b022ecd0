// Splat extraction. Conventions: see splats.hpp.
//
// Speed: a brick that provably has no splat (one side of the surface and |d| >= kSurfaceNear
// throughout, neighbours' faces on the same side) is skipped after one counting pass. Others
// are copied once into a 10^3 array with a one-voxel ring (faces only: the splat of a voxel
// reads its six neighbours, never edge or corner neighbours); the test runs on 64-bit words,
// one per brick slice (the brick's inside and near bits, the ring's inside bits, shifted onto
// each other; splat_slices.hpp, shared with splats_around.cpp's bricksAroundChanges), and only
// voxels whose bit survives are visited. Their splats
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
#include "splat_slices.hpp"
#include "stencil.hpp"

namespace marzipan {

namespace {

using namespace splat_slices;

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

}  // namespace marzipan
