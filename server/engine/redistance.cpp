#include "redistance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "chunked_pass.hpp"
#include "redistance_flags.hpp"
#include "simd_width.hpp"  // MARZIPAN_SSE2, MARZIPAN_AVX2
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif
#include "volume.hpp"

namespace marzipan {

namespace {

using namespace march_flag;
using namespace redistance_flags;
// The caller's progress: checked per z-slice of the dense passes and per piece of the band
// list; the classification counts as this share of the call, the march as the rest.
constexpr double kSetupShare = 0.3;

// A voxel of a moved box's shell keeps its value when its foot point lies this far (vu) or
// further from the cells the tool may have moved the surface through: the foot point is
// estimated by central differences, which err by a fraction of a voxel near the surface.
constexpr double kFootMargin = 0.5;
// ... and when its central-difference gradient is this close to unit length (elsewhere, a kink
// or a stale value, the foot point says nothing).
constexpr double kFootGradientTolerance = 0.25;

// RedistanceOptions::direct: a far voxel nearer than kDirectReach (the far voxels the
// classification looks at one by one) takes d / |grad d| when every neighbour lies more than
// kDirectMargin inside the band (nearer its edge the motion's upwind differences read the
// clamped +-band beyond it and squeeze the values) and |grad d| is within kDirectTolerance of 1
// (elsewhere a kink: surfaces meeting or parting, where only the march finds the nearer one).
// Reaching to 2 vu with a margin of 0.25 saved 2% more of a dab's instructions, but the bump
// of thirty blobs at one centre then read 0.48 at its crease (test_tools.cpp; 0.29 here).
constexpr float kDirectReach = 1.75f;
constexpr float kDirectMargin = 0.5f;
constexpr double kDirectTolerance = 0.1;

// A moved box (RedistanceOptions::movedBoxes) as the shell's tests read it: the range per axis
// a foot point must lie in to be near its cells (the points within 1 vu of its voxels).
struct MovedBox {
  double footLo[3], footHi[3];
  int zLo, zHi, yLo, yHi;  // its cells' range on y and z
};
// A moved box near one row of the band list: its cells' x-range [xLo, xHi] and their squared
// distance from the row in y and z.
struct NearBox {
  int xLo, xHi, yz2;
  const MovedBox* box;
};

enum class Shell { Kept, UpperBound, Reset };

// What becomes of far voxel i at p, outside every box of RedistanceOptions::movedBoxes, of a
// region whose surface moved only through the cells touching those boxes (the points within
// 1 vu of their voxels). near: the moved boxes near p's row (the others are too far to matter).
// hasLo(a) / hasHi(a): whether it has a neighbour below / above on axis a.
template <class HasLo, class HasHi>
[[gnu::always_inline]] inline Shell shellClass(const float* v, std::size_t i, Int3 p, const std::size_t* stride,
                                               HasLo&& hasLo, HasHi&& hasHi, std::span<const NearBox> near) {
  const double value = v[i];
  // Squared distances to the cells are whole numbers: compared exactly with value^2 (a float
  // squared is exact in double).
  const double value2 = value * value;
  const bool nearer = std::any_of(near.begin(), near.end(), [&](const NearBox& b) {
    const int dx = p.x < b.xLo ? b.xLo - p.x : std::max(0, p.x - b.xHi);
    return double(dx * dx + b.yz2) < value2;
  });
  if (!nearer) return Shell::Kept;  // no moved cell is nearer than its value
  double grad[3];
  for (int a = 0; a < 3; ++a) {
    const std::size_t st = stride[a];
    grad[a] = hasLo(a) && hasHi(a) ? 0.5 * (double(v[i + st]) - double(v[i - st])) : 0.0;
  }
  const double len = std::sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2]);
  if (!(std::fabs(len - 1) <= kFootGradientTolerance)) return Shell::Reset;
  double foot[3];
  for (int a = 0; a < 3; ++a) foot[a] = p[a] - value * grad[a] / len;
  const bool nearMoved = std::any_of(near.begin(), near.end(), [&](const NearBox& b) {
    for (int a = 0; a < 3; ++a)
      if (foot[a] < b.box->footLo[a] || foot[a] > b.box->footHi[a]) return false;
    return true;
  });
  return nearMoved ? Shell::Reset : Shell::UpperBound;
}

// The dense passes over a tool's box visit ten to twenty times more voxels than its band, so
// they test 16 voxels per step (the flags pass 32 with AVX2). Each gives exactly what its scalar
// loop gives.

// Bit k set when |v[k]| != band (16 voxels).
std::uint32_t nearMask16(const float* v, float band) {
#if defined(MARZIPAN_SSE2)
  const __m128 abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)), b = _mm_set1_ps(band);
  std::uint32_t m = 0;
  for (int k = 0; k < 4; ++k)
    m |= std::uint32_t(_mm_movemask_ps(_mm_cmpneq_ps(_mm_and_ps(_mm_loadu_ps(v + 4 * k), abs), b))) << (4 * k);
  return m;
#else
  std::uint32_t m = 0;
  for (int k = 0; k < 16; ++k) m |= std::uint32_t(std::fabs(v[k]) != band) << k;
  return m;
#endif
}

// A tool's grid is split into fixed pieces (z-slabs of the grid, runs of the band list), each
// worked on alone: the result does not depend on the thread count. Grids smaller than this
// are worked on the calling thread only: waking the pool would cost more than it saves.
constexpr std::size_t kParallelVoxels = std::size_t(1) << 17;
constexpr int kSlabSlices = 8;
constexpr std::size_t kListPiece = std::size_t(1) << 13;

// One run of the band list: its kept voxels to normalize (with their new values) and its
// unknown voxels to reset.
struct ListPiece {
  // Sized for a whole piece once, then written through counts (a push_back per voxel cost as
  // much as deciding what the voxel is).
  std::vector<std::uint32_t> kept;
  std::vector<float> scaled;
  std::vector<std::uint32_t> farUnknown;
  std::size_t keptCount = 0, farCount = 0;
  // Scratch of the pass: the moved boxes near the current z-slice (with the rows [yFrom, yTo]
  // within reach of them, and their NearBox for the slice: a row adds only dy^2, as a stroke's
  // rows hold a few voxels each and rebuilding the boxes per row cost a quarter of the pass)
  // and row (the first nearCount of near).
  struct NearZ {
    NearBox slice;
    int yFrom, yTo, yLo, yHi;
  };
  std::vector<NearZ> nearZ;
  std::vector<NearBox> near;
  std::size_t nearCount = 0;
};

struct Scratch {
  std::vector<std::uint8_t> flags;
  BandVoxels band;
  std::vector<ListPiece> pieces;
  std::vector<FlagPiece> flagPieces;
  std::vector<Box> resetBoxes, normalizeBoxes;
  std::vector<MovedBox> moved;
};
Scratch& scratch() {
  thread_local Scratch s;
  return s;
}

// fn(piece) for piece in [0, n): on the pool when `parallel`, else here.
template <class F>
void forPieces(ThreadPool& pool, bool parallel, std::size_t n, F&& fn) {
  if (parallel && n > 1) {
    pool.parallelFor(n, fn);
  } else {
    for (std::size_t k = 0; k < n; ++k) fn(k);
  }
}

}  // namespace

namespace {

// Where a run of whole rows of a z-slice (RowRun) has got to: the grid index of the current
// row's first voxel, of the next row's, and its y.
struct RowCursor {
  std::size_t rowStart, rowEnd;
  int y;
};

// Appends the voxels of g whose value is not +-band among the count voxels from grid index row
// on, at out's positions n, n + 1, ...: the caller has sized out's arrays for all of them (a
// push_back per voxel cost several times the test of the 16 voxels around it). RowRun: they are
// part of a run of whole rows of a z-slice, followed from one row to the next by cursor; else
// they lie in row (y, z) from x = lo on.
template <bool RowRun>
[[gnu::always_inline]] inline void collectRun(const DenseGrid& g, std::size_t row, std::size_t count, int lo, int y, int z,
                                              float band, BandVoxels& out, std::size_t& n, RowCursor& cursor) {
  const float* v = g.v.data() + row;
  std::uint32_t* const index = out.index.data();
  Int3* const point = out.point.data();
  auto add = [&](std::uint32_t near, std::size_t x) __attribute__((always_inline)) {
    while (near) {
      const std::size_t i = row + x + std::size_t(__builtin_ctz(near));
      near &= near - 1;
      index[n] = std::uint32_t(i);
      if constexpr (RowRun) {
        while (i >= cursor.rowEnd) cursor.rowStart = cursor.rowEnd, cursor.rowEnd += g.sx, ++cursor.y;
        point[n++] = {g.box.lo.x + int(i - cursor.rowStart), cursor.y, z};
      } else {
        point[n++] = {lo + int(i - row), y, z};
      }
    }
  };
  // Far voxels are the rule: test 16 at a time without a branch, then visit the others. The
  // last few voxels are tested in a block that ends at the run's end (the bits of voxels
  // already tested shifted out), or, in a run shorter than 16, in one that reads past it (the
  // bits past it dropped) where the grid goes on that far.
  std::size_t x = 0;
  for (; x + 16 <= count; x += 16) add(nearMask16(v + x, band), x);
  if (x >= count) return;  // also an empty run
  if (count >= 16) {
    add(nearMask16(v + count - 16, band) >> (16 - (count - x)), x);
  } else if (row + 16 <= g.v.size()) {
    add(nearMask16(v, band) & ((std::uint32_t(1) << count) - 1), 0);
  } else {
    for (; x < count; ++x)
      if (std::fabs(v[x]) != band) add(1, x);
  }
}

// BandVoxels::collect with parts: the parts clipped to the box, and a slice's x range per row.
struct PartsScratch {
  std::vector<Box> parts;
  std::vector<int> xLo, xHi;
};
PartsScratch& partsScratch() {
  thread_local PartsScratch s;
  return s;
}

// Makes room in out for n + count voxels. The arrays keep the last list's length between calls
// and grow by an eighth when short: what they hold past n is written before it is read, but a
// resize writes every element it adds (the vectors' own growth keeps reallocations few).
inline void reserveRow(BandVoxels& out, std::size_t n, std::size_t count) {
  const std::size_t want = n + count;
  if (out.index.size() >= want) return;
  const std::size_t size = std::max(want, out.index.size() + out.index.size() / 8);
  out.index.resize(size);
  out.point.resize(size);
}

}  // namespace

void BandVoxels::collect(const DenseGrid& g, const Box& b, float band, const ProgressShare& progress) {
  box = b.intersect(g.box);
  if (box.empty()) {
    index.clear();
    point.clear();
    progress.advance(1);
    return;
  }
  std::size_t n = 0;
  RowCursor unused{};
  // A box as wide as the grid (a local tool's) is one run of whole rows per z-slice, taken in
  // pieces of kRunPiece voxels (the arrays grow by no more than that past the list): a short
  // row's ends cost more than its voxels.
  constexpr std::size_t kRunPiece = 1024;
  const bool wide = box.lo.x == g.box.lo.x && box.hi.x == g.box.hi.x;
  const std::size_t width = std::size_t(std::max(0, box.hi.x - box.lo.x));
  const std::size_t sliceRun = std::size_t(std::max(0, box.hi.y - box.lo.y)) * width;
  for (int z = box.lo.z; z < box.hi.z; ++z) {
    progress.check();
    if (wide) {
      const std::size_t first = g.index({box.lo.x, box.lo.y, z});
      RowCursor cursor{first, first + g.sx, box.lo.y};
      for (std::size_t o = 0; o < sliceRun; o += kRunPiece) {
        const std::size_t count = std::min(kRunPiece, sliceRun - o);
        reserveRow(*this, n, count);
        collectRun<true>(g, first + o, count, 0, 0, z, band, *this, n, cursor);
      }
      continue;
    }
    for (int y = box.lo.y; y < box.hi.y; ++y) {
      reserveRow(*this, n, width);
      collectRun<false>(g, g.index({box.lo.x, y, z}), width, box.lo.x, y, z, band, *this, n, unused);
    }
  }
  index.resize(n);
  point.resize(n);
  progress.advance(1);
}

void BandVoxels::collect(const DenseGrid& g, const Box& b, std::span<const Box> parts, float band,
                         const ProgressShare& progress) {
  const Box whole = b.intersect(g.box);
  if (whole.empty()) return collect(g, b, band, progress);
  PartsScratch& s = partsScratch();
  s.parts.clear();
  for (const Box& p : parts)
    if (const Box c = p.intersect(whole); !c.empty()) {
      if (c == whole) return collect(g, b, band, progress);
      s.parts.push_back(c);
    }
  box = whole;
  std::size_t n = 0;
  RowCursor unused{};
  // Per z-slice, each row's x range from the first to the last x of the parts holding it: along
  // a stroke the parts holding a row overlap, so that is their union. Kept per row of the box
  // (y - box.lo.y), each part widening the rows it holds.
  const std::size_t rows = std::size_t(box.hi.y - box.lo.y);
  s.xLo.resize(rows);
  s.xHi.resize(rows);
  for (int z = box.lo.z; z < box.hi.z; ++z) {
    progress.check();
    std::fill(s.xLo.begin(), s.xLo.end(), box.hi.x);
    std::fill(s.xHi.begin(), s.xHi.end(), box.lo.x);
    int yFrom = box.hi.y, yTo = box.lo.y;
    for (const Box& p : s.parts) {
      if (z < p.lo.z || z >= p.hi.z) continue;
      // Copies, which no store to the rows can alias: the loop is then vectorized.
      const int pLo = p.lo.x, pHi = p.hi.x, y0 = p.lo.y - box.lo.y, y1 = p.hi.y - box.lo.y;
      int* const lo = s.xLo.data();
      int* const hi = s.xHi.data();
      for (int y = y0; y < y1; ++y) lo[y] = std::min(lo[y], pLo), hi[y] = std::max(hi[y], pHi);
      yFrom = std::min(yFrom, p.lo.y), yTo = std::max(yTo, p.hi.y);
    }
    if (yFrom >= yTo) continue;
    // Room for the whole rectangle of the slice's rows once, rather than row by row.
    reserveRow(*this, n, std::size_t(yTo - yFrom) * std::size_t(box.hi.x - box.lo.x));
    std::size_t row = g.index({g.box.lo.x, yFrom, z});  // the grid index of the row's x = g.box.lo.x
    for (int y = yFrom; y < yTo; ++y, row += g.sx) {
      const int lo = s.xLo[std::size_t(y - box.lo.y)], hi = s.xHi[std::size_t(y - box.lo.y)];
      if (lo >= hi) continue;
      collectRun<false>(g, row + std::size_t(lo - g.box.lo.x), std::size_t(hi - lo), lo, y, z, band, *this, n, unused);
    }
  }
  index.resize(n);
  point.resize(n);
  progress.advance(1);
}

void BandVoxels::collect(const DenseGrid& g, const Box& b, float band, const Volume& vol) {
  box = b.intersect(g.box);
  std::size_t n = 0;
  RowCursor unused{};
  const Box stored = box.intersect(vol.domain());
  if (stored.empty()) {
    index.clear();
    point.clear();
    return;
  }
  // Per row of bricks (by, bz): the x-runs of stored bricks, clipped to the box, in increasing x.
  // Then the rows in index order (z, y), each through its brick row's runs.
  const Box bricks = Bricks::bricksOf(stored);
  const Int3 nb = bricks.size();
  std::vector<std::vector<std::pair<int, int>>> runs(std::size_t(nb.y) * std::size_t(nb.z));
  for (int bz = bricks.lo.z; bz < bricks.hi.z; ++bz)
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by) {
      auto& row = runs[std::size_t(by - bricks.lo.y) + std::size_t(nb.y) * std::size_t(bz - bricks.lo.z)];
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        float u;
        if (!vol.brickData({bx, by, bz}, &u)) continue;
        const int lo = std::max(bx * kBrickSide, stored.lo.x), hi = std::min((bx + 1) * kBrickSide, stored.hi.x);
        if (!row.empty() && row.back().second == lo) {
          row.back().second = hi;
        } else {
          row.push_back({lo, hi});
        }
      }
    }
  for (int z = stored.lo.z; z < stored.hi.z; ++z)
    for (int y = stored.lo.y; y < stored.hi.y; ++y) {
      const auto& row = runs[std::size_t(Bricks::brickOf(y) - bricks.lo.y) +
                             std::size_t(nb.y) * std::size_t(Bricks::brickOf(z) - bricks.lo.z)];
      for (const auto& [lo, hi] : row) {
        reserveRow(*this, n, std::size_t(hi - lo));
        collectRun<false>(g, g.index({lo, y, z}), std::size_t(hi - lo), lo, y, z, band, *this, n, unused);
      }
    }
  index.resize(n);
  point.resize(n);
}

std::size_t redistanceScratchBytes() {
  const Scratch& s = scratch();
  std::size_t bytes = s.flags.capacity() + 16 * s.band.index.capacity();
  for (const FlagPiece& p : s.flagPieces) bytes += 2 * (p.resetCount.capacity() + p.markedCount.capacity()) + p.interior.capacity() + p.pos.capacity() + p.flip.capacity();
  return bytes + marchScratchBytes();
}

void trimRedistanceScratch(std::size_t voxels) {
  Scratch& s = scratch();
  if (s.flags.capacity() > voxels || s.band.index.capacity() > voxels) s = Scratch();
  trimMarchScratch(voxels);
}

MarchStats redistanceRegion(DenseGrid& g, const Box& region, float band, Outside outside,
                            const RedistanceOptions& options, ThreadPool& pool) {
  const ProgressShare& progress = options.progress;
  const Box r = region.intersect(g.box);
  if (r.empty()) return {};
  Scratch& s = scratch();
  s.flags.resize(g.v.size());
  std::uint8_t* const allFlags = s.flags.data();
  float* const values = g.v.data();
  const bool parallel = pool.threads() > 1 && g.v.size() >= kParallelVoxels;

  // The region's voxels to reset, and where kept voxels are normalized.
  auto clipped = [&](std::span<const Box> boxes, std::vector<Box>& out) {
    out.clear();
    for (const Box& b : boxes) out.push_back(b.intersect(r));
    if (boxes.empty()) out.push_back(r);
    std::sort(out.begin(), out.end(), [](const Box& a, const Box& b) { return a.lo.x < b.lo.x; });
    return std::span<const Box>(out);
  };
  const std::span<const Box> reset = clipped(options.resetBoxes, s.resetBoxes);
  // The marked boxes: the moved boxes when there are any (kept voxels are normalized only
  // there, and a voxel there is reset without looking at the boxes again), else the boxes
  // where kept voxels are normalized.
  const std::span<const Box> moved = options.movedBoxes;
  const bool normalizeKept = options.normalizeKept;
  const std::span<const Box> marked =
      !moved.empty() ? clipped(moved, s.normalizeBoxes)
      : normalizeKept
          ? clipped(options.normalizeBoxes.empty() ? std::span<const Box>{&r, 1} : options.normalizeBoxes,
                    s.normalizeBoxes)
          : std::span<const Box>{};

  // Every voxel: a source (or ignored) with its sign, or reset in the reset boxes (unless on
  // the side that is already exact), marked in the marked boxes; interior = 2 voxels from
  // every face. One write per voxel, slab by slab of whole z-slices on the pool.
  {
    const FlagLayout layout{reset, marked,
                            std::uint8_t(outside == Outside::Source ? (kKnown | kFrozen) : (kIgnored | kFrozen)),
                            options.exactSide};
    const int sz = g.size.z;
    const std::size_t slabs = parallel ? std::size_t((sz + kSlabSlices - 1) / kSlabSlices) : 1;
    if (s.flagPieces.size() < slabs) s.flagPieces.resize(slabs);
    forPieces(pool, parallel, slabs, [&](std::size_t slab) {
      const int z0 = parallel ? int(slab) * kSlabSlices : 0, z1 = parallel ? std::min(sz, z0 + kSlabSlices) : sz;
      flagSlices(g, allFlags, layout, z0, z1, s.flagPieces[slab], progress);
    });
  }

  // Only voxels of the band list can be kept, or need a value written before the march.
  const BandVoxels* list = options.band;
  if (!list || !(list->box == r.grown(1).intersect(g.box))) {
    s.band.collect(g, r.grown(1), band, {progress.progress, 0});
    list = &s.band;
  }
  // Reads only the values as they were (the kept test and the normalization read neighbours),
  // and writes only its own voxels' flags; the values are written once every piece is done.
  const std::size_t pieces = (list->index.size() + kListPiece - 1) / kListPiece;
  if (s.pieces.size() < pieces) s.pieces.resize(pieces);
  const std::size_t stride[3] = {1, g.sx, g.sxy};
  s.moved.clear();
  for (const Box& b : moved) {
    MovedBox m{{}, {}, b.lo.z - 1, b.hi.z, b.lo.y - 1, b.hi.y};
    for (int a = 0; a < 3; ++a) m.footLo[a] = b.lo[a] - 1 - kFootMargin, m.footHi[a] = b.hi[a] + kFootMargin;
    s.moved.push_back(m);
  }
  const double reach = double(band) + kFootMargin;
  const bool direct = options.direct;
  const float directLimit = band - kDirectMargin;
  forPieces(pool, parallel, pieces, [&](std::size_t piece) {
    progress.check();
    // Copies the compiler sees are not stored to: a store to a flag byte may alias anything,
    // and would have the pointers captured by reference loaded again for every voxel.
    std::uint8_t* const flags = allFlags;
    const float* const v = values;
    ListPiece& out = s.pieces[piece];
    const std::size_t begin = piece * kListPiece, end = std::min(list->index.size(), begin + kListPiece);
    if (out.kept.size() < end - begin) {
      out.kept.resize(end - begin);
      out.scaled.resize(end - begin);
      out.farUnknown.resize(end - begin);
    }
    std::uint32_t* const kept = out.kept.data();
    float* const scaled = out.scaled.data();
    std::uint32_t* const farUnknown = out.farUnknown.data();
    std::size_t keptCount = 0, farCount = 0;
    // The moved boxes that may matter to the list's current row (y, z): those whose cells lie
    // within band + kFootMargin of it on both axes (no voxel further from them can be nearer
    // than its value, inside them, or have its foot point near them). The list is in index
    // order, so its rows come one after the other.
    int rowY = std::numeric_limits<int>::min(), rowZ = rowY;
    auto cellDistance = [](int x, int lo, int hi) { return x < lo ? lo - x : std::max(0, x - hi); };
    // Rebuilt only when the row changes: a row holds a few shell voxels, looked at one by one.
    auto newRow = [&](Int3 p) __attribute__((noinline)) {
      if (p.z != rowZ) {
        rowZ = p.z;
        out.nearZ.clear();
        for (std::size_t b = 0; b < s.moved.size(); ++b) {
          const MovedBox& m = s.moved[b];
          const int dz = cellDistance(p.z, m.zLo, m.zHi);
          if (!(dz < reach)) continue;
          // The rows within reach: cell distance dy up to w on y.
          int w = 0;
          while (double((w + 1) * (w + 1) + dz * dz) < reach * reach) ++w;
          out.nearZ.push_back({{moved[b].lo.x - 1, moved[b].hi.x, dz * dz, &m}, m.yLo - w, m.yHi + w, m.yLo, m.yHi});
        }
        if (out.near.size() < out.nearZ.size()) out.near.resize(out.nearZ.size());
      }
      rowY = p.y;
      NearBox* const near = out.near.data();
      std::size_t count = 0;
      for (const ListPiece::NearZ& n : out.nearZ) {
        if (p.y < n.yFrom || p.y > n.yTo) continue;
        const int dy = cellDistance(p.y, n.yLo, n.yHi);
        near[count] = n.slice;
        near[count++].yz2 += dy * dy;
      }
      out.nearCount = count;
    };
    auto nearRow = [&](Int3 p) __attribute__((always_inline)) -> std::span<const NearBox> {
      if (p.y != rowY || p.z != rowZ) newRow(p);
      return {out.near.data(), out.nearCount};
    };
    const std::uint32_t* const index = list->index.data();
    const Int3* const point = list->point.data();
    // Voxel k of the list, i in the grid, with flags f: reset and not yet frozen. Inner: it has
    // neighbours on every side (2 voxels from every face), so no position is read for that.
    auto classify = [&](auto innerTag, std::size_t k, std::uint32_t i, std::uint8_t f) __attribute__((always_inline)) {
      constexpr bool inner = decltype(innerTag)::value;
      auto hasLo = [&](int a) { return inner || point[k][a] > g.box.lo[a]; };
      auto hasHi = [&](int a) { return inner || point[k][a] + 1 < g.box.hi[a]; };
      const float value = v[i];
      const bool neg = value < 0;
      // Further than sqrt(3) from the surface: neither on it nor adjacent to it.
      bool adjacent = value == 0;  // on the surface itself (grid-aligned faces, edges, corners)
      if (!adjacent && std::fabs(value) < 1.75f) {
        if constexpr (inner) {
#if defined(MARZIPAN_SSE2)
          // The six neighbours' signs (as `< 0` reads them) in two compares: bits 0 and 2 of
          // the row around i (an inner voxel has two more on every side), bits 3 to 6 across.
          const __m128 zero = _mm_setzero_ps();
          const int row = _mm_movemask_ps(_mm_cmplt_ps(_mm_loadu_ps(v + i - 1), zero)) & 5;
          const __m128 across = _mm_setr_ps(v[i - stride[1]], v[i + stride[1]], v[i - stride[2]], v[i + stride[2]]);
          const int signs = row | _mm_movemask_ps(_mm_cmplt_ps(across, zero)) << 3;
          adjacent = signs != (neg ? (5 | 15 << 3) : 0);
#else
          adjacent = ((v[i - 1] < 0) != neg) | ((v[i + 1] < 0) != neg) | ((v[i - stride[1]] < 0) != neg) |
                     ((v[i + stride[1]] < 0) != neg) | ((v[i - stride[2]] < 0) != neg) | ((v[i + stride[2]] < 0) != neg);
#endif
        } else {
          for (int a = 0; a < 3 && !adjacent; ++a) {
            if (hasLo(a)) adjacent = (v[i - stride[a]] < 0) != neg;
            if (!adjacent && hasHi(a)) adjacent = (v[i + stride[a]] < 0) != neg;
          }
        }
      }
      if (!adjacent) {
        if (!moved.empty() && !(f & kMarked)) {
          const Int3 p = point[k];
          const Shell c = shellClass(v, i, p, stride, hasLo, hasHi, nearRow(p));
          if (c != Shell::Reset) {
            flags[i] = std::uint8_t(f | (c == Shell::Kept ? (kKnown | kFrozen) : kUpperBound));
            return;
          }
        }
        if (direct && std::fabs(value) < kDirectReach) {
          // A source of the march, as a kept voxel is; its value is written with theirs.
          double g2 = 0;
          bool usable = true;
          for (int a = 0; a < 3 && usable; ++a) {
            const std::size_t st = stride[a];
            usable = hasLo(a) && hasHi(a) && std::fabs(v[i - st]) < directLimit && std::fabs(v[i + st]) < directLimit;
            if (!usable) break;
            const double d = 0.5 * (double(v[i + st]) - double(v[i - st]));
            g2 += d * d;
          }
          const double len = std::sqrt(g2);
          if (usable && std::fabs(len - 1) <= kDirectTolerance) {
            flags[i] = std::uint8_t(f | (kKnown | kFrozen));
            kept[keptCount] = i;
            scaled[keptCount++] = float(double(value) / len);
            return;
          }
        }
        farUnknown[farCount++] = i;
        return;
      }
      flags[i] = std::uint8_t(f | kKnown | kFrozen);
      if (!normalizeKept || !(f & kMarked)) return;
      double g2 = 0;
      for (int a = 0; a < 3; ++a) {
        const std::size_t st = stride[a];
        const bool l = hasLo(a), h = hasHi(a);
        const double lo = l ? v[i - st] : v[i];
        const double hi = h ? v[i + st] : v[i];
        const double span = (l ? 1 : 0) + (h ? 1 : 0);
        const double d = span > 0 ? (hi - lo) / span : 0;
        g2 += d * d;
      }
      // The surface crosses an edge to an opposite-sign neighbour within t = v / (v - v_n) vu,
      // so no distance exceeds the nearest such t; this bounds the result where the gradient
      // is small (a kink between two surfaces), where v / |grad| alone would explode.
      const double val = value;
      double bound = 1.0;
      for (int a = 0; a < 3; ++a) {
        const std::size_t st = stride[a];
        if (hasLo(a) && (v[i - st] < 0) != neg) bound = std::min(bound, val / (val - v[i - st]));
        if (hasHi(a) && (v[i + st] < 0) != neg) bound = std::min(bound, val / (val - v[i + st]));
      }
      const double len = std::sqrt(g2);
      const double mag = len > 1e-6 ? std::min(std::fabs(val) / len, bound) : bound;
      kept[keptCount] = i;
      scaled[keptCount++] = float(std::copysign(mag, val));
    };
    // Marked voxels, or all without moved boxes, are not looked at by the shell's tests.
    const std::uint8_t noShell = moved.empty() ? 0xff : kMarked;
    for (std::size_t k = begin; k < end; ++k) {
      const std::uint32_t i = index[k];
      const std::uint8_t f = flags[i];
      if ((f & (kReset | kFrozen)) != kReset) continue;  // a source, or ignored
      // The most common kind in a large region, decided before the rest (as classify would):
      // too far from the surface to be adjacent to it (NaN included), and reset.
      if (!(std::fabs(v[i]) < 1.75f) && (f & noShell)) {
        farUnknown[farCount++] = i;
        continue;
      }
      if (f & kInterior) {
        classify(std::true_type{}, k, i, f);
      } else {
        classify(std::false_type{}, k, i, f);
      }
    }
    out.keptCount = keptCount;
    out.farCount = farCount;
  });
  // The marcher starts every unknown voxel at +-band; those off the list are there already.
  forPieces(pool, parallel, pieces, [&](std::size_t piece) {
    const ListPiece& in = s.pieces[piece];
    for (std::size_t j = 0; j < in.keptCount; ++j) values[in.kept[j]] = in.scaled[j];
    for (std::size_t j = 0; j < in.farCount; ++j) {
      const std::uint32_t i = in.farUnknown[j];
      values[i] = values[i] < 0 ? -band : band;
    }
  });
  progress.advance(kSetupShare);
  return fastMarchClassified(g, s.flags, list->index, band, options.order, pool, progress.part(1 - kSetupShare),
                             options.parallelSides);
}

void redistanceVolume(Volume& vol, ThreadPool& pool) {
  const float band = vol.band();
  // Kept voxels need one neighbour, distances reach band + 1 voxels: a margin of band + 3.
  const int margin = int(std::ceil(band)) + 3;
  chunkedPass(vol, margin, pool, [&](DenseGrid& g, const Box&, ThreadPool&) {
    redistanceRegion(g, g.box.grown(-1), band, Outside::Ignored);
  });
  // Every voxel is a distance again, but those the mask held (channels.hpp), which keep theirs.
  if (vol.paintedBricks() == 0) vol.clearBrickDrift();
}

}  // namespace marzipan
