// Splat extraction. Conventions: see splats.hpp.
//
// Speed: a brick that provably has no splat (one side of the surface and |d| >= kSurfaceNear
// throughout, neighbours' faces on the same side) is skipped after one counting pass. Others
// are copied once into a 10^3 array with a one-voxel ring (faces only: the splat of a voxel
// reads its six neighbours, never edge or corner neighbours); the test runs as byte
// operations over that array, and only voxels whose byte survives are visited.
#include "splats.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "brick_table.hpp"
#include "errors.hpp"
#include "simd_width.hpp"  // MARZIPAN_SSE2
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
    // Counts rather than a min/max: integer sums vectorize without fast-math.
    int out = 0, in = 0;
    for (int i = 0; i < kBrickVoxels; ++i) {
      out += own[i] >= kSurfaceNear;
      in += own[i] <= -kSurfaceNear;
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
  std::fill(g, g + kPadVoxels, band);
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

// The 8 bytes of 0/1 of a brick row (the first at the lowest address) packed into 8 bits, bit i
// from byte i. Rows of another length need another packing: the static_assert above holds the
// side at the wire's 8. p may be read up to 16 bytes on (the padded array has them).
std::uint32_t packBytes(const std::uint8_t* p) {
#if defined(MARZIPAN_SSE2)
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
  return std::uint32_t(_mm_movemask_epi8(_mm_slli_epi16(v, 7))) & 0xffu;
#else
  std::uint64_t w = 0;
  for (int i = 0; i < 8; ++i) w |= std::uint64_t(p[i]) << (8 * i);
  return std::uint32_t((w * 0x0102040810204080ull) >> 56);
#endif
}

// The bytes over the padded array: inside[i] = g[i] < 0, near[i] = |g[i]| < kSurfaceNear, 0 or 1.
void classify(const float* g, std::uint8_t* inside, std::uint8_t* near) {
  int i = 0;
#if defined(MARZIPAN_SSE2)
  // Sixteen at a time: the comparisons' all-ones lanes narrowed by saturating packs (-1 stays
  // -1), then masked to 1.
  const __m128 zero = _mm_setzero_ps(), nearBound = _mm_set1_ps(kSurfaceNear);
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128i one = _mm_set1_epi8(1);
  for (; i + 16 <= kPadVoxels; i += 16) {
    __m128i in[4], nr[4];
    for (int k = 0; k < 4; ++k) {
      const __m128 v = _mm_loadu_ps(g + i + 4 * k);
      in[k] = _mm_castps_si128(_mm_cmplt_ps(v, zero));
      nr[k] = _mm_castps_si128(_mm_cmplt_ps(_mm_and_ps(v, magnitude), nearBound));
    }
    const __m128i inBytes = _mm_packs_epi16(_mm_packs_epi32(in[0], in[1]), _mm_packs_epi32(in[2], in[3]));
    const __m128i nearBytes = _mm_packs_epi16(_mm_packs_epi32(nr[0], nr[1]), _mm_packs_epi32(nr[2], nr[3]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(inside + i), _mm_and_si128(inBytes, one));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(near + i), _mm_and_si128(nearBytes, one));
  }
#endif
  for (; i < kPadVoxels; ++i) {
    inside[i] = g[i] < 0;
    near[i] = std::fabs(g[i]) < kSurfaceNear;
  }
}

float clampPosition(float q, float origin) {
  return std::clamp(q, origin + kPosLow, origin + kPosLow + kPosStep * float(kPosMax));
}

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

  // The test as bytes over the whole padded array (plain loops the compiler vectorizes):
  // inside[i] = d < 0, then surface[i] = near | any of the six neighbours on the other side.
  // Entries on the ring come out meaningless and are never used.
  // packBytes reads 16 bytes from a brick row's start: they lie in [kLo, kHi), all set.
  std::uint8_t inside[kPadVoxels], near[kPadVoxels], surface[kPadVoxels];
  classify(g, inside, near);
  constexpr int kLo = kPad * kPad, kHi = kPadVoxels - kPad * kPad;
  for (int i = kLo; i < kHi; ++i) {
    const std::uint8_t s = inside[i];
    surface[i] = near[i] | (s ^ inside[i - 1]) | (s ^ inside[i + 1]) |
                 (s ^ inside[i - kPad]) | (s ^ inside[i + kPad]) | (s ^ inside[i - kPad * kPad]) |
                 (s ^ inside[i + kPad * kPad]);
  }

  const Int3 o = Bricks::origin(b);
  const Int3 dims = vol.dims();
  const int xs = std::min(kBrickSide, dims.x - o.x), ys = std::min(kBrickSide, dims.y - o.y),
            zs = std::min(kBrickSide, dims.z - o.z);
  const std::uint32_t xBits = (1u << xs) - 1;

  Splat found[kBrickVoxels];
  std::uint16_t voxelOf[kBrickVoxels];  // each splat's voxel, Bricks::index
  int count = 0;
  for (int z = 0; z < zs; ++z)
    for (int y = 0; y < ys; ++y)
      for (std::uint32_t m = packBytes(surface + padIndex(0, y, z)) & xBits; m; m &= m - 1) {
        const int x = std::countr_zero(m);
        const int c = padIndex(x, y, z);
        const float d = g[c];
        // Twice the gradient: only its direction is kept.
        const GradStencil st = GradStencil::inArray(g + c, kStride[0], kStride[1], kStride[2]);
        const float gx = st.difference(0), gy = st.difference(1), gz = st.difference(2);
        const float len2 = gx * gx + gy * gy + gz * gz;
        const float px = float(o.x + x), py = float(o.y + y), pz = float(o.z + z);
        voxelOf[count] = std::uint16_t(Bricks::index(x, y, z));
        Splat& sp = found[count++];
        sp = {px, py, pz, 0, 0, 1};
        if (len2 > 0) {
          const float inv = 1 / std::sqrt(len2);
          sp.nx = gx * inv;
          sp.ny = gy * inv;
          sp.nz = gz * inv;
          sp.x = clampPosition(px - d * sp.nx, float(o.x));
          sp.y = clampPosition(py - d * sp.ny, float(o.y));
          sp.z = clampPosition(pz - d * sp.nz, float(o.z));
        }
      }
  out.points.assign(found, found + count);
  // The voxels of a brick without channels all read the base colour, weight 0: its points take
  // the session's base colour on the client, and carry nothing.
  if (const BrickPaint* paint = own && count > 0 ? vol.brickPaint(b) : nullptr) {
    out.texels.resize(std::size_t(count));
    for (int i = 0; i < count; ++i) {
      const Texel& t = paint->t[voxelOf[i]];
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

// Whether the layer of a changed brick that its neighbour on side s of axis a reads differs, bit
// for bit, between before and after: read in place (rows of 8 where the layer has them), stopping
// at the first difference.
bool layerDiffers(const BrickChange& c, int a, int s, float band) {
  const float* x = c.before.data ? c.before.data->v : nullptr;
  const float* y = c.after.data ? c.after.data->v : nullptr;
  const float ux = c.before.inside ? -band : band, uy = c.after.inside ? -band : band;
  if (!x && !y) return std::bit_cast<std::uint32_t>(ux) != std::bit_cast<std::uint32_t>(uy);
  const int layer = s < 0 ? 0 : kBrickSide - 1;
  // The layer as kBrickSide rows of kBrickSide floats: row j starts at first + j * rowStep, its
  // floats step by `step`.
  const int first = a == 0 ? layer : a == 1 ? kBrickSide * layer : kBrickSide * kBrickSide * layer;
  const int step = a == 0 ? kBrickSide : 1;
  const int rowStep = a == 2 ? kBrickSide : kBrickSide * kBrickSide;
  float rx[kBrickSide], ry[kBrickSide];
  for (int j = 0; j < kBrickSide; ++j) {
    const int r = first + j * rowStep;
    if (step == 1 && x && y) {
      if (std::memcmp(x + r, y + r, sizeof rx) != 0) return true;
      continue;
    }
    for (int i = 0; i < kBrickSide; ++i) {
      rx[i] = x ? x[r + i * step] : ux;
      ry[i] = y ? y[r + i * step] : uy;
    }
    if (std::memcmp(rx, ry, sizeof rx) != 0) return true;
  }
  return false;
}

}  // namespace

std::vector<Int3> bricksAroundChanges(const Volume& vol, const std::vector<BrickChange>& changes) {
  const float band = vol.band();
  std::vector<Int3> out;
  out.reserve(changes.size() * 7);
  for (const auto& c : changes) {
    if (inGrid(vol, c.brick)) out.push_back(c.brick);
    for (int a = 0; a < 3; ++a)
      for (int s = -1; s <= 1; s += 2) {
        Int3 nb = c.brick;
        nb[a] += s;
        // The neighbour's splats read only that layer of this brick: when it is the same bit
        // for bit, they are too (unless the neighbour changed itself, and is listed for that).
        if (inGrid(vol, nb) && layerDiffers(c, a, s, band)) out.push_back(nb);
      }
  }
  auto order = [](Int3 a, Int3 b) { return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x); };
  std::sort(out.begin(), out.end(), order);
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace marzipan
