// A Volume's distances (volume.hpp): the brick tiles, reading, sampling, and the scatter, diff
// and publish that change them. Its colour and mask channels are in volume_channels.cpp.
#include "volume.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <sstream>
#if defined(__SSE2__)
#include <xmmintrin.h>
#endif
// Whole brick rows (8 floats, one AVX vector) are also compared, copied and filled by AVX2
// functions (simd_width.hpp); they only compare and move values, so both give the same results.
#include "simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "errors.hpp"
#include "stencil.hpp"
#include "thread_pool.hpp"

namespace marzipan {

namespace {

// make_shared keeps the brick and its control block in one allocation; this is its size.
constexpr std::size_t kBrickAllocation = sizeof(Brick) + 2 * sizeof(void*) + 16;
constexpr std::size_t kPaintAllocation = sizeof(BrickPaint) + 2 * sizeof(void*) + 16;

#if defined(MARZIPAN_AVX2)

// rowsMayDiffer for whole brick rows: one vector a row.
__attribute__((target("avx2"))) bool wholeRowsMayDifferAvx2(const float* s, std::size_t sStride, const float* old,
                                                            float uniform, int rows) {
  __m256 ne = _mm256_setzero_ps();
  if (old) {
    for (int r = 0; r < rows; ++r, s += sStride, old += kBrickSide)
      ne = _mm256_or_ps(ne, _mm256_cmp_ps(_mm256_loadu_ps(s), _mm256_loadu_ps(old), _CMP_NEQ_UQ));
  } else {
    const __m256 u = _mm256_set1_ps(uniform);
    for (int r = 0; r < rows; ++r, s += sStride) ne = _mm256_or_ps(ne, _mm256_cmp_ps(_mm256_loadu_ps(s), u, _CMP_NEQ_UQ));
  }
  return _mm256_movemask_ps(ne) != 0;
}

__attribute__((target("avx2"))) void copyWholeBrickAvx2(float* to, std::size_t sx, std::size_t sxy, const float* from) {
  for (int z = 0; z < kBrickSide; ++z, to += sxy) {
    float* row = to;
    for (int y = 0; y < kBrickSide; ++y, row += sx, from += kBrickSide) _mm256_storeu_ps(row, _mm256_loadu_ps(from));
  }
}

__attribute__((target("avx2"))) void fillWholeBrickAvx2(float* to, std::size_t sx, std::size_t sxy, float value) {
  const __m256 v = _mm256_set1_ps(value);
  for (int z = 0; z < kBrickSide; ++z, to += sxy) {
    float* row = to;
    for (int y = 0; y < kBrickSide; ++y, row += sx) _mm256_storeu_ps(row, v);
  }
}
#endif

// One row of n voxels: does some source value differ from the stored one (old, or `uniform`
// where old is null) once clamped to +-band? Throws on NaN, which passes std::clamp and would
// reach every reader.
bool rowDiffers(const float* s, const float* old, float uniform, int n, float band) {
  int nan = 0, differs = 0;
  int x = 0;
#if defined(MARZIPAN_SSE2)
  // Four at a time; min/max is std::clamp for every value but NaN, and NaN throws.
  const __m128 lo = _mm_set1_ps(-band), hi = _mm_set1_ps(band), u = _mm_set1_ps(uniform);
  __m128 bad = _mm_setzero_ps(), ne = _mm_setzero_ps();
  for (; x + 4 <= n; x += 4) {
    const __m128 sv = _mm_loadu_ps(s + x);
    bad = _mm_or_ps(bad, _mm_cmpunord_ps(sv, sv));
    ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_max_ps(_mm_min_ps(sv, hi), lo), old ? _mm_loadu_ps(old + x) : u));
  }
  nan = _mm_movemask_ps(bad), differs = _mm_movemask_ps(ne);
#endif
  for (; x < n; ++x) nan |= s[x] != s[x], differs |= std::clamp(s[x], -band, band) != (old ? old[x] : uniform);
  if (nan) throw EngineError(ErrorKind::InvalidArgument, "src", "values must not be NaN");
  return differs != 0;
}

// Rows of n voxels, `rows` of them, the source's r-th at s + r * sStride, the stored one's at
// old + r * kBrickSide: is some source value not exactly equal (==) to the stored one? When
// all are, none is NaN and each clamps to itself (stored values lie in [-band, band]), so the
// rows do not change: the cheap test that almost every row of a tool's region passes.
bool rowsMayDiffer(const float* s, std::size_t sStride, const float* old, float uniform, int n, int rows) {
#if defined(MARZIPAN_SSE2)
  if (n == kBrickSide) {  // whole brick rows, the rule: two vectors a row, one test for all rows
#if defined(MARZIPAN_AVX2)
    if (simd_width::useAvx2()) return wholeRowsMayDifferAvx2(s, sStride, old, uniform, rows);
#endif
    __m128 ne = _mm_setzero_ps();
    if (old) {
      for (int r = 0; r < rows; ++r, s += sStride, old += kBrickSide) {
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s), _mm_loadu_ps(old)));
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s + 4), _mm_loadu_ps(old + 4)));
      }
    } else {
      const __m128 u = _mm_set1_ps(uniform);
      for (int r = 0; r < rows; ++r, s += sStride) {
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s), u));
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s + 4), u));
      }
    }
    return _mm_movemask_ps(ne) != 0;
  }
  if (n >= 4) {  // a row cut by the region: its first and last four voxels (overlapping) cover it
    const int t = n - 4;
    __m128 ne = _mm_setzero_ps();
    if (old) {
      for (int r = 0; r < rows; ++r, s += sStride, old += kBrickSide) {
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s), _mm_loadu_ps(old)));
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s + t), _mm_loadu_ps(old + t)));
      }
    } else {
      const __m128 u = _mm_set1_ps(uniform);
      for (int r = 0; r < rows; ++r, s += sStride) {
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s), u));
        ne = _mm_or_ps(ne, _mm_cmpneq_ps(_mm_loadu_ps(s + t), u));
      }
    }
    return _mm_movemask_ps(ne) != 0;
  }
#endif
  int differs = 0;
  for (int r = 0; r < rows; ++r, s += sStride) {
    const float* d = old ? old + r * kBrickSide : nullptr;
    for (int x = 0; x < n; ++x) differs |= s[x] != (d ? d[x] : uniform);
  }
  return differs != 0;
}

// n voxels (1 to kBrickSide) copied from a brick row.
void copyShortRow(float* to, const float* from, int n) {
#if defined(MARZIPAN_SSE2)
  if (n >= 4) {
    _mm_storeu_ps(to, _mm_loadu_ps(from));
    _mm_storeu_ps(to + n - 4, _mm_loadu_ps(from + n - 4));
    return;
  }
#endif
  for (int x = 0; x < n; ++x) to[x] = from[x];
}

// n voxels (1 to kBrickSide) set to one value.
void fillShortRow(float* to, float value, int n) {
#if defined(MARZIPAN_SSE2)
  if (n >= 4) {
    const __m128 v = _mm_set1_ps(value);
    _mm_storeu_ps(to, v);
    _mm_storeu_ps(to + n - 4, v);
    return;
  }
#endif
  for (int x = 0; x < n; ++x) to[x] = value;
}

// A whole brick's voxels copied into a grid of strides sx (y) and sxy (z), its first voxel at `to`.
void copyWholeBrick(float* to, std::size_t sx, std::size_t sxy, const float* from) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return copyWholeBrickAvx2(to, sx, sxy, from);
#endif
  for (int z = 0; z < kBrickSide; ++z, to += sxy) {
    float* row = to;
    for (int y = 0; y < kBrickSide; ++y, row += sx, from += kBrickSide) std::memcpy(row, from, sizeof(float) * kBrickSide);
  }
}

// A whole brick of the grid set to one value.
void fillWholeBrick(float* to, std::size_t sx, std::size_t sxy, float value) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return fillWholeBrickAvx2(to, sx, sxy, value);
#endif
#if defined(MARZIPAN_SSE2)
  const __m128 v = _mm_set1_ps(value);
  for (int z = 0; z < kBrickSide; ++z, to += sxy) {
    float* row = to;
    for (int y = 0; y < kBrickSide; ++y, row += sx) {
      _mm_storeu_ps(row, v);
      _mm_storeu_ps(row + 4, v);
    }
  }
#else
  for (int z = 0; z < kBrickSide; ++z, to += sxy) {
    float* row = to;
    for (int y = 0; y < kBrickSide; ++y, row += sx) std::fill(row, row + kBrickSide, value);
  }
#endif
}

// The mask (channels.hpp): each voxel of a new brick moved back towards its old value by its
// weight, all the way at 255. Old and new lie within the band, and so does what lies between.
// Whether some voxel still differs from the old brick.
bool holdMasked(float* now, const float* old, const BrickPaint& paint) {
  bool differs = false;
  for (int i = 0; i < kBrickVoxels; ++i) {
    const int w = paint.t[i].mask;
    if (w == 255) {
      now[i] = old[i];
    } else if (w != 0) {
      now[i] = old[i] + (1.0f - float(w) / 255.0f) * (now[i] - old[i]);
    }
    differs = differs || now[i] != old[i];
  }
  return differs;
}

}  // namespace

Volume::Volume(Int3 dims, float band) : dims_(dims), band_(band) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < kBrickSide || dims[a] > kMaxDomainSide) {
      std::ostringstream s;
      s << "each side must be between " << kBrickSide << " and " << kMaxDomainSide << " voxels (got "
        << dims.x << "x" << dims.y << "x" << dims.z << ")";
      throw EngineError(dims[a] > kMaxDomainSide ? ErrorKind::TooLarge : ErrorKind::InvalidArgument, "size",
                        s.str());
    }
  }
  requireRange(band, 2.0, 8.0, "band");
  for (int a = 0; a < 3; ++a) {
    brickDims_[a] = Bricks::gridOf(dims)[a];
    tileDims_[a] = (brickDims_[a] + kTileSide - 1) / kTileSide;
  }
  const std::size_t nt = std::size_t(tileDims_.x) * tileDims_.y * tileDims_.z;
  tiles_.assign(nt, nullptr);
  tileInside_.assign(nt, 0);
}

std::size_t Volume::tileIndex(Int3 b) const {
  return std::size_t(b.x / kTileSide) +
         std::size_t(tileDims_.x) * (std::size_t(b.y / kTileSide) + std::size_t(tileDims_.y) * (b.z / kTileSide));
}

int Volume::slotInTile(Int3 b) {
  return (b.x % kTileSide) + kTileSide * ((b.y % kTileSide) + kTileSide * (b.z % kTileSide));
}

bool Volume::sharesTile(const Volume& other, Int3 b) const {
  const std::size_t ti = tileIndex(b);
  if (tiles_[ti] != other.tiles_[ti] || (!tiles_[ti] && tileInside_[ti] != other.tileInside_[ti])) return false;
  const PaintTile* mine = paintTiles_.empty() ? nullptr : paintTiles_[ti].get();
  const PaintTile* theirs = other.paintTiles_.empty() ? nullptr : other.paintTiles_[ti].get();
  return mine == theirs;
}

BrickRef Volume::brick(Int3 b) const {
  const std::size_t ti = tileIndex(b);
  const Tile* t = tiles_[ti].get();
  if (!t) return {nullptr, tileInside_[ti] != 0};
  const int s = slotInTile(b);
  if (paintedBricks_ != 0)
    if (const PaintTile* pt = paintTiles_[ti].get()) return {t->bricks[s], t->inside[s], pt->paint[s]};
  return {t->bricks[s], t->inside[s]};
}

const BrickPaint* Volume::brickPaint(Int3 b) const {
  if (paintedBricks_ == 0) return nullptr;
  const PaintTile* pt = paintTiles_[tileIndex(b)].get();
  return pt ? pt->paint[slotInTile(b)].get() : nullptr;
}

const float* Volume::brickData(Int3 b, float* uniformValue) const {
  const std::size_t ti = tileIndex(b);
  const Tile* t = tiles_[ti].get();
  bool inside;
  if (t) {
    const int s = slotInTile(b);
    if (const Brick* br = t->bricks[s].get()) return br->v;
    inside = t->inside[s];
  } else {
    inside = tileInside_[ti] != 0;
  }
  *uniformValue = inside ? -band_ : band_;
  return nullptr;
}

float Volume::at(Int3 p) const {
  if (p.x < 0 || p.y < 0 || p.z < 0 || p.x >= dims_.x || p.y >= dims_.y || p.z >= dims_.z) return band_;
  float u;
  const float* d = brickData(Bricks::brickOf(p), &u);
  return d ? d[Bricks::indexOf(p)] : u;
}

void Volume::gather(const Box& box, float* out) const {
  const Int3 s = box.size();
  if (box.empty()) return;
  const std::size_t sx = std::size_t(s.x), sxy = sx * std::size_t(s.y);
  const Box inside = box.intersect(domain());
  const float air = band_;
  if (inside.empty()) {
    std::fill(out, out + sxy * std::size_t(s.z), air);
    return;
  }
  // Everything outside the domain reads as air: the slices, rows and row ends it covers.
  if (inside.voxels() != box.voxels()) {
    const int x0 = inside.lo.x - box.lo.x, x1 = inside.hi.x - box.lo.x;
    for (int z = box.lo.z; z < box.hi.z; ++z) {
      float* slice = out + sxy * std::size_t(z - box.lo.z);
      if (z < inside.lo.z || z >= inside.hi.z) {
        std::fill(slice, slice + sxy, air);
        continue;
      }
      for (int y = box.lo.y; y < box.hi.y; ++y) {
        float* row = slice + sx * std::size_t(y - box.lo.y);
        if (y < inside.lo.y || y >= inside.hi.y) {
          std::fill(row, row + sx, air);
          continue;
        }
        std::fill(row, row + x0, air);
        std::fill(row + x1, row + sx, air);
      }
    }
  }
  // Inside, brick by brick (one table look-up each).
  const Box bricks = Bricks::bricksOf(inside);
  for (int bz = bricks.lo.z; bz < bricks.hi.z; ++bz)
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const Int3 o = Bricks::origin({bx, by, bz});
        const Box here = Bricks::box({bx, by, bz}).intersect(inside);
        float u;
        const float* d = brickData({bx, by, bz}, &u);
        const int n = here.hi.x - here.lo.x;
        // Locals only: the stores through `out` may alias members, which would be reloaded
        // every row otherwise.
        float* const first = out + std::size_t(here.lo.x - box.lo.x) + sx * std::size_t(here.lo.y - box.lo.y) +
                             sxy * std::size_t(here.lo.z - box.lo.z);
        const int ny = here.hi.y - here.lo.y, nz = here.hi.z - here.lo.z;
        const float* const src = d ? d + Bricks::index(here.lo.x - o.x, here.lo.y - o.y, here.lo.z - o.z) : nullptr;
        // Whole bricks are the rule (most of a tool's box, most of them uniform): their rows
        // copied or filled by fixed-size stores, the pointers stepped, no branch per row.
        if (n == kBrickSide && ny == kBrickSide && nz == kBrickSide) {
          if (src) {
            copyWholeBrick(first, sx, sxy, src);
          } else {
            fillWholeBrick(first, sx, sxy, u);
          }
          continue;
        }
        // A brick cut by the box: rows of 1 to 8 voxels, the longer ones by two overlapping
        // 4-wide stores instead of a call.
        for (int z = 0; z < nz; ++z) {
          float* row = first + sxy * std::size_t(z);
          if (src) {
            const float* from = src + Bricks::index(0, 0, z);
            for (int y = 0; y < ny; ++y, row += sx, from += kBrickSide) copyShortRow(row, from, n);
          } else {
            for (int y = 0; y < ny; ++y, row += sx) fillShortRow(row, u, n);
          }
        }
      }
}

double Volume::sample(Vec3 p) const {
  const int i = int(std::floor(p.x)), j = int(std::floor(p.y)), k = int(std::floor(p.z));
  const double fx = p.x - i, fy = p.y - j, fz = p.z - k;
  double c[2][2][2];
  const Int3 l = Bricks::localOf(Int3{i, j, k});
  if (i >= 0 && j >= 0 && k >= 0 && i + 1 < dims_.x && j + 1 < dims_.y && k + 1 < dims_.z &&
      l.x < kBrickSide - 1 && l.y < kBrickSide - 1 && l.z < kBrickSide - 1) {
    // The eight corners lie in one brick of the domain (most points): one table look-up, the
    // values at() would read.
    float u;
    const float* d = brickData(Bricks::brickOf(Int3{i, j, k}), &u);
    const int base = Bricks::index(l);
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) c[dz][dy][dx] = d ? d[base + Bricks::index(dx, dy, dz)] : u;
  } else {
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) c[dz][dy][dx] = at(i + dx, j + dy, k + dz);
  }
  const double c00 = c[0][0][0] + fx * (c[0][0][1] - c[0][0][0]);
  const double c10 = c[0][1][0] + fx * (c[0][1][1] - c[0][1][0]);
  const double c01 = c[1][0][0] + fx * (c[1][0][1] - c[1][0][0]);
  const double c11 = c[1][1][0] + fx * (c[1][1][1] - c[1][1][0]);
  const double c0 = c00 + fy * (c10 - c00);
  const double c1 = c01 + fy * (c11 - c01);
  return c0 + fz * (c1 - c0);
}

Vec3 Volume::gradient(Vec3 p) const {
  const int i = int(std::floor(p.x)), j = int(std::floor(p.y)), k = int(std::floor(p.z));
  const double f[3] = {p.x - i, p.y - j, p.z - k};
  double c[2][2][2];
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) c[dx][dy][dz] = at(i + dx, j + dy, k + dz);
  Vec3 g;
  // d/dx of the trilinear interpolant: bilinear blend in (y,z) of the x-differences, and so on.
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, e = (a + 2) % 3;
    double sum = 0;
    for (int ub = 0; ub < 2; ++ub)
      for (int ue = 0; ue < 2; ++ue) {
        int hi[3], lo[3];
        hi[a] = 1, lo[a] = 0, hi[b] = lo[b] = ub, hi[e] = lo[e] = ue;
        const double w = (ub ? f[b] : 1 - f[b]) * (ue ? f[e] : 1 - f[e]);
        sum += w * (c[hi[0]][hi[1]][hi[2]] - c[lo[0]][lo[1]][lo[2]]);
      }
    g[a] = sum;
  }
  return g;
}

Vec3 Volume::towardSurface(Vec3 p, int steps) const {
  for (int i = 0; i < steps; ++i) {
    const double d = sample(p);
    const Vec3 g = gradient(p);
    if (d == 0 || !(std::fabs(d) < band()) || !(length(g) > 0.5)) break;
    p = p - normalized(g) * (d / length(g));
  }
  return p;
}

Vec3 Volume::voxelGradient(Int3 p) const {
  return GradStencil::around(p, [this](Int3 q) { return at(q); }).gradient();
}

std::size_t Volume::memoryBytes() const {
  std::size_t tiles = 0;
  for (const auto& t : tiles_) tiles += t ? 1 : 0;
  std::size_t paintTiles = 0;
  for (const auto& t : paintTiles_) paintTiles += t ? 1 : 0;
  std::size_t driftTiles = 0;
  for (const auto& t : driftTiles_) driftTiles += t ? 1 : 0;
  return presentBricks_ * kBrickAllocation + tiles * sizeof(Tile) + tiles_.size() * sizeof(tiles_[0]) +
         tileInside_.size() + paintedBricks_ * kPaintAllocation + paintTiles * sizeof(PaintTile) +
         paintTiles_.size() * sizeof(paintTiles_[0]) + driftTiles * sizeof(DriftTile) +
         driftTiles_.size() * sizeof(driftTiles_[0]) + sizeof(*this);
}

std::vector<BrickChange> Volume::scatter(const Box& region, const float* src, const Box& srcBox) {
  return scatter(region, src, srcBox, ThreadPool::serial());
}

std::vector<BrickChange> Volume::scatter(const Box& region, const float* src, const Box& srcBox, ThreadPool& pool) {
  auto changes = diff(region, src, srcBox, pool);
  extendChannels(changes);
  publish(changes, true);
  return changes;
}

bool Volume::brickChanges(Int3 b, const Box& here, const float* old, float uniform, const float* src,
                          const Box& srcBox) const {
  const Int3 ss = srcBox.size();
  const Int3 o = Bricks::origin(b);
  const std::size_t sx = std::size_t(ss.x), sxy = sx * std::size_t(ss.y);
  const int n = here.hi.x - here.lo.x, ny = here.hi.y - here.lo.y;
  // Slice by slice: the exact-equality test first, the clamping, NaN-refusing one only for a
  // slice that fails it, and stop at the first row that really differs. The rows read before
  // that row are the ones a row-by-row test would read, so a NaN among them throws alike (a
  // NaN further on throws while the brick is rebuilt).
  for (int z = here.lo.z; z < here.hi.z; ++z) {
    const float* s = src + (std::size_t(here.lo.x - srcBox.lo.x) + sx * std::size_t(here.lo.y - srcBox.lo.y) +
                            sxy * std::size_t(z - srcBox.lo.z));
    const float* d = old ? old + Bricks::index(here.lo.x - o.x, here.lo.y - o.y, z - o.z) : nullptr;
    if (!rowsMayDiffer(s, sx, d, uniform, n, ny)) continue;
    for (int y = 0; y < ny; ++y)
      if (rowDiffers(s + sx * std::size_t(y), d ? d + y * kBrickSide : nullptr, uniform, n, band_)) return true;
  }
  return false;
}

std::vector<BrickChange> Volume::diff(const Box& region, const float* src, const Box& srcBox) const {
  return diff(region, src, srcBox, ThreadPool::serial());
}

std::vector<BrickChange> Volume::diff(const Box& region, const float* src, const Box& srcBox,
                                      ThreadPool& pool) const {
  const Box r = region.intersect(domain());
  std::vector<BrickChange> changes;
  if (r.empty()) return changes;
  if (!srcBox.contains(r.lo) || !srcBox.contains(r.hi - Int3{1, 1, 1}))
    throw EngineError(ErrorKind::InvalidArgument, "srcBox", "must contain the region to write");
  const Box bricks = Bricks::bricksOf(r);
  const int layers = bricks.hi.z - bricks.lo.z;
  if (pool.threads() == 1 || layers == 1 || r.voxels() < kParallelDiffVoxels) {
    diffLayers(r, bricks, bricks.lo.z, bricks.hi.z, src, srcBox, changes);
    return changes;
  }
  // One piece per brick layer, whatever the thread count; joined in order, the changes are
  // those of the loop above.
  std::vector<std::vector<BrickChange>> pieces(std::size_t(layers), std::vector<BrickChange>{});
  pool.parallelFor(pieces.size(), [&](std::size_t k) {
    const int bz = bricks.lo.z + int(k);
    diffLayers(r, bricks, bz, bz + 1, src, srcBox, pieces[k]);
  });
  std::size_t total = 0;
  for (const auto& p : pieces) total += p.size();
  changes.reserve(total);
  for (auto& p : pieces) std::move(p.begin(), p.end(), std::back_inserter(changes));
  return changes;
}

void Volume::diffLayers(const Box& r, const Box& bricks, int bz0, int bz1, const float* src, const Box& srcBox,
                        std::vector<BrickChange>& changes) const {
  const Int3 ss = srcBox.size();
  for (int bz = bz0; bz < bz1; ++bz)
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const Int3 b{bx, by, bz};
        const Int3 o = Bricks::origin(b);
        const Box here = Bricks::box(b).intersect(r);
        // Most bricks of a tool's region do not change: find out before allocating one (or
        // taking a reference, whose count is shared with other threads).
        float uniform;
        const float* stored = brickData(b, &uniform);
        if (!brickChanges(b, here, stored, uniform, src, srcBox)) continue;
        BrickRef old = brick(b);
        // Channels stay with a brick that stays stored; the mask holds its voxels back.
        std::shared_ptr<const BrickPaint> paint = old.paint;
        const bool masked = paint && paint->masked;
        // Every voxel is set below: no zero-fill first.
        auto nb = std::make_shared_for_overwrite<Brick>();
        // Voxels of the brick outside the region keep their old values (the rule is the whole brick).
        if (here != Bricks::box(b)) {
          // A brick is a grid of strides kBrickSide and kBrickSide^2: the gather's whole-brick copies.
          if (old.data) {
            copyWholeBrick(nb->v, kBrickSide, kBrickSide * kBrickSide, old.data->v);
          } else {
            fillWholeBrick(nb->v, kBrickSide, kBrickSide * kBrickSide, old.inside ? -band_ : band_);
          }
        }
        // Row pointers stepped, not recomputed: the loop runs for every voxel of a changed brick.
        const std::size_t sx = std::size_t(ss.x), sxy = sx * std::size_t(ss.y);
        const float* const s0 = src + (std::size_t(here.lo.x - srcBox.lo.x) + sx * std::size_t(here.lo.y - srcBox.lo.y) +
                                       sxy * std::size_t(here.lo.z - srcBox.lo.z));
        float* const d0 = nb->v + Bricks::index(here.lo.x - o.x, here.lo.y - o.y, here.lo.z - o.z);
        const int n = here.hi.x - here.lo.x, ny = here.hi.y - here.lo.y, nz = here.hi.z - here.lo.z;
        // The bounds in locals (stores through d may alias band_) and the NaN test after the
        // brick: the loops have no branch per voxel. nb is dropped when it throws.
        const float lo = -band_, hi = band_;
#if defined(MARZIPAN_SSE2)
        if (here == Bricks::box(b) && !masked) {
          // A whole brick (in the domain, as the region is): the written values also tell
          // whether it is uniform, the test canonicalBrick would make reading them again.
          const __m128 vlo = _mm_set1_ps(lo), vhi = _mm_set1_ps(hi);
          __m128 bad = _mm_setzero_ps(), notOut = _mm_setzero_ps(), notIn = _mm_setzero_ps();
          float* d = nb->v;
          for (int z = 0; z < kBrickSide; ++z)
            for (int y = 0; y < kBrickSide; ++y, d += kBrickSide) {
              const float* const s = s0 + sx * std::size_t(y) + sxy * std::size_t(z);
              const __m128 a = _mm_loadu_ps(s), c = _mm_loadu_ps(s + 4);
              bad = _mm_or_ps(bad, _mm_or_ps(_mm_cmpunord_ps(a, a), _mm_cmpunord_ps(c, c)));
              const __m128 ca = _mm_max_ps(_mm_min_ps(a, vhi), vlo), cc = _mm_max_ps(_mm_min_ps(c, vhi), vlo);
              _mm_storeu_ps(d, ca);
              _mm_storeu_ps(d + 4, cc);
              notOut = _mm_or_ps(notOut, _mm_or_ps(_mm_cmpneq_ps(ca, vhi), _mm_cmpneq_ps(cc, vhi)));
              notIn = _mm_or_ps(notIn, _mm_or_ps(_mm_cmpneq_ps(ca, vlo), _mm_cmpneq_ps(cc, vlo)));
            }
          if (_mm_movemask_ps(bad)) throw EngineError(ErrorKind::InvalidArgument, "src", "values must not be NaN");
          const bool allOut = _mm_movemask_ps(notOut) == 0, allIn = _mm_movemask_ps(notIn) == 0;
          changes.push_back({b, std::move(old),
                             allOut || allIn ? BrickRef{nullptr, allIn} : BrickRef{std::move(nb), false, std::move(paint)}});
          continue;
        }
#endif
        int nan = 0;
#if defined(MARZIPAN_SSE2)
        if (n >= 4) {
          // The first and last four voxels of each row (overlapping but for whole brick rows):
          // min/max is std::clamp but for NaN, and a voxel written twice gets the same value.
          const int t = n - 4;
          const __m128 vlo = _mm_set1_ps(lo), vhi = _mm_set1_ps(hi);
          __m128 bad = _mm_setzero_ps();
          for (int z = 0; z < nz; ++z) {
            const float* s = s0 + sxy * std::size_t(z);
            float* d = d0 + Bricks::index(0, 0, z);
            for (int y = 0; y < ny; ++y, s += sx, d += kBrickSide) {
              const __m128 a = _mm_loadu_ps(s), c = _mm_loadu_ps(s + t);
              bad = _mm_or_ps(bad, _mm_or_ps(_mm_cmpunord_ps(a, a), _mm_cmpunord_ps(c, c)));
              _mm_storeu_ps(d, _mm_max_ps(_mm_min_ps(a, vhi), vlo));
              _mm_storeu_ps(d + t, _mm_max_ps(_mm_min_ps(c, vhi), vlo));
            }
          }
          nan = _mm_movemask_ps(bad);
        } else
#endif
        {
          for (int z = 0; z < nz; ++z)
            for (int y = 0; y < ny; ++y) {
              const float* const s = s0 + sx * std::size_t(y) + sxy * std::size_t(z);
              float* const d = d0 + Bricks::index(0, y, z);
              for (int x = 0; x < n; ++x) {
                const float value = s[x];
                nan |= value != value;
                d[x] = std::clamp(value, lo, hi);
              }
            }
        }
        if (nan) throw EngineError(ErrorKind::InvalidArgument, "src", "values must not be NaN");
        if (masked && !holdMasked(nb->v, old.data->v, *paint)) continue;
        // brickChanges found a voxel whose clamped value differs (!=) from the stored one (and
        // the mask let one move): the new brick cannot equal the old, byte for byte or as the
        // same uniform side.
        BrickRef now = canonicalBrick(b, std::move(nb));
        if (now.data) now.paint = std::move(paint);
        changes.push_back({b, std::move(old), std::move(now)});
      }
}

BrickRef Volume::canonicalBrick(Int3 brick, std::shared_ptr<Brick> data) const {
  const Int3 o = Bricks::origin(brick);
  const Box inDomain = Bricks::box(brick).intersect(domain());
  bool allOut = true, allIn = true;
  if (inDomain.size() == Int3{kBrickSide, kBrickSide, kBrickSide}) {
    // Every brick of a domain whose sides are multiples of the brick side: no voxel to blank, and most
    // bricks an edit writes are mixed, which the first few voxels tell (2% of a loaded server's
    // CPU went to the general loop below).
    // Sixteen voxels a step: the bricks at the band's outer edge hold +-band nearly throughout.
    const float* v = data->v;
    const float band = band_;
#if defined(MARZIPAN_SSE2)
    const __m128 out = _mm_set1_ps(band), in = _mm_set1_ps(-band);
    __m128 notOut = _mm_setzero_ps(), notIn = _mm_setzero_ps();
    for (int i = 0; i < kBrickVoxels; i += 16) {
      for (int k = i; k < i + 16; k += 4) {
        const __m128 a = _mm_loadu_ps(v + k);
        notOut = _mm_or_ps(notOut, _mm_cmpneq_ps(a, out));
        notIn = _mm_or_ps(notIn, _mm_cmpneq_ps(a, in));
      }
      if (_mm_movemask_ps(notOut) != 0 && _mm_movemask_ps(notIn) != 0) break;
    }
    allOut = _mm_movemask_ps(notOut) == 0;
    allIn = _mm_movemask_ps(notIn) == 0;
#else
    for (int i = 0; i < kBrickVoxels && (allOut || allIn); i += 16) {
      int out = 0, in = 0;
      for (int k = i; k < i + 16; ++k) out += v[k] == band, in += v[k] == -band;
      allOut = allOut && out == 16;
      allIn = allIn && in == 16;
    }
#endif
    if (allOut || allIn) return {nullptr, allIn};
    return {std::move(data), false};
  }
  for (int z = 0; z < kBrickSide; ++z)
    for (int y = 0; y < kBrickSide; ++y)
      for (int x = 0; x < kBrickSide; ++x) {
        float& v = data->v[Bricks::index(x, y, z)];
        if (!inDomain.contains(o + Int3{x, y, z})) {
          v = band_;
          continue;
        }
        allOut = allOut && v == band_;
        allIn = allIn && v == -band_;
      }
  if (allOut || allIn) return {nullptr, allIn};
  return {std::move(data), false};
}

template <class SlotAt>
void Volume::setSlots(std::size_t n, SlotAt slotAt) {
  if (n == 0) return;
  // The slots by tile, in their given order within a tile; sorted as (tile, position) pairs, so
  // that no BrickRef is copied (each copy of a stored brick is an atomic count).
  std::vector<std::pair<std::size_t, std::size_t>> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = {tileIndex(slotAt(i).first), i};
  std::sort(order.begin(), order.end());
  std::size_t i = 0;
  while (i < n) {
    const std::size_t ti = order[i].first;
    // Every tile touched by this edit is copied once: readers of older versions keep theirs.
    // Copy-constructed from the old tile when there is one (not zeroed first, then assigned).
    std::shared_ptr<Tile> t;
    if (const Tile* old = tiles_[ti].get()) {
      t = std::make_shared<Tile>(*old);
    } else {
      t = std::make_shared<Tile>();
      if (tileInside_[ti]) t->inside.set();
    }
    std::shared_ptr<PaintTile> pt;  // the tile's channels, copied at the first slot whose channels change
    for (; i < n && order[i].first == ti; ++i) {
      const auto [b, refPtr] = slotAt(order[i].second);
      const int s = slotInTile(b);
      const BrickRef& ref = *refPtr;
      t->present += (ref.data ? 1 : 0) - (t->bricks[s] ? 1 : 0);
      presentBricks_ += (ref.data ? 1 : 0);
      presentBricks_ -= (t->bricks[s] ? 1 : 0);
      t->bricks[s] = ref.data;
      t->inside[s] = ref.data ? false : ref.inside;
      // A uniform slot carries no channels.
      const BrickPaint* paint = ref.data ? ref.paint.get() : nullptr;
      const BrickPaint* had = pt                                         ? pt->paint[s].get()
                              : !paintTiles_.empty() && paintTiles_[ti] ? paintTiles_[ti]->paint[s].get()
                                                                         : nullptr;
      if (paint == had) continue;
      if (!pt) {
        if (paintTiles_.empty()) paintTiles_.assign(tiles_.size(), nullptr);
        pt = paintTiles_[ti] ? std::make_shared<PaintTile>(*paintTiles_[ti]) : std::make_shared<PaintTile>();
      }
      pt->present += (paint ? 1 : 0) - (had ? 1 : 0);
      paintedBricks_ = paintedBricks_ + (paint ? 1 : 0) - (had ? 1 : 0);
      pt->paint[s] = paint ? ref.paint : nullptr;
    }
    if (pt) {
      paintTiles_[ti] = pt->present != 0 ? std::move(pt) : nullptr;
      // Painted back to nothing: as a volume never painted, in memory too.
      if (paintedBricks_ == 0) paintTiles_.clear();
    }
    // A tile whose real bricks are all uniform on one side collapses to a null tile.
    bool collapse = t->present == 0;
    bool first = true, side = false;
    const Int3 tb{int(ti % tileDims_.x) * kTileSide, int((ti / tileDims_.x) % tileDims_.y) * kTileSide,
                  int(ti / (std::size_t(tileDims_.x) * tileDims_.y)) * kTileSide};
    for (int z = tb.z; collapse && z < std::min(tb.z + kTileSide, brickDims_.z); ++z)
      for (int y = tb.y; collapse && y < std::min(tb.y + kTileSide, brickDims_.y); ++y)
        for (int x = tb.x; collapse && x < std::min(tb.x + kTileSide, brickDims_.x); ++x) {
          const bool in = t->inside[slotInTile({x, y, z})];
          if (first) side = in, first = false;
          collapse = in == side;
        }
    if (collapse) {
      tiles_[ti] = nullptr;
      tileInside_[ti] = side ? 1 : 0;
    } else {
      tiles_[ti] = std::move(t);
    }
  }
}

std::vector<BrickChange> Volume::fill(bool inside) {
  std::vector<BrickChange> changes;
  for (int bz = 0; bz < brickDims_.z; ++bz)
    for (int by = 0; by < brickDims_.y; ++by)
      for (int bx = 0; bx < brickDims_.x; ++bx) {
        const Int3 b{bx, by, bz};
        BrickRef old = brick(b);
        if (!old.data && old.inside == inside) continue;
        changes.push_back({b, std::move(old), BrickRef{nullptr, inside}});
      }
  publish(changes, true);
  clearBrickDrift();  // no band voxel is left
  return changes;
}

std::vector<BrickChange> Volume::clearOutside(const Box& keep) {
  const Box k = keep.intersect(domain());
  std::vector<BrickChange> changes;
  for (int bz = 0; bz < brickDims_.z; ++bz)
    for (int by = 0; by < brickDims_.y; ++by)
      for (int bx = 0; bx < brickDims_.x; ++bx) {
        const Int3 b{bx, by, bz};
        const Box inDomain = Bricks::box(b).intersect(domain());
        if (inDomain.intersect(k) == inDomain) continue;
        BrickRef old = brick(b);
        if (!old.data && !old.inside) continue;
        auto nb = std::make_shared<Brick>();
        const float was = old.inside ? -band_ : band_;
        bool differs = false;
        for (int i = 0; i < kBrickVoxels; ++i) {
          const float before = old.data ? old.data->v[i] : was;
          nb->v[i] = k.contains(Bricks::origin(b) + Bricks::local(i)) ? before : band_;
          differs = differs || nb->v[i] != before;
        }
        if (old.paint && old.paint->masked) differs = holdMasked(nb->v, old.data->v, *old.paint);
        if (!differs) continue;
        BrickRef now = canonicalBrick(b, std::move(nb));
        if (now.data) now.paint = old.paint;
        changes.push_back({b, std::move(old), std::move(now)});
      }
  extendChannels(changes);
  publish(changes, true);
  return changes;
}

void Volume::publish(const std::vector<BrickChange>& changes, bool forward) {
  setSlots(changes.size(), [&](std::size_t i) {
    const BrickChange& c = changes[i];
    return std::pair<Int3, const BrickRef*>{c.brick, forward ? &c.after : &c.before};
  });
}

}  // namespace marzipan
