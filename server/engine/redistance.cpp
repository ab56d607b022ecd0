#include "redistance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "chunked_pass.hpp"
#include "volume.hpp"

namespace marzipan {

namespace {

using namespace march_flag;
constexpr std::uint8_t kReset = kCallerA;      // in the region and to be reset unless kept
constexpr std::uint8_t kMarked = kCallerB;  // in a box where kept voxels are normalized
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

// Squared distance from p to the cells touching box b's voxels, the points within 1 vu of them.
double squaredDistanceToCells(Int3 p, const Box& b) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = b.lo[a] - 1, hi = b.hi[a], x = p[a];
    const double d = x < lo ? lo - x : (x > hi ? x - hi : 0.0);
    d2 += d * d;
  }
  return d2;
}

enum class Shell { Kept, UpperBound, Reset };

// What becomes of far voxel i at p, outside every box of `moved`, of a region whose surface
// moved only through the cells of those boxes (RedistanceOptions::movedBoxes). hasLo(a) /
// hasHi(a): whether it has a neighbour below / above on axis a.
template <class HasLo, class HasHi>
Shell shellClass(const DenseGrid& g, const float* v, std::size_t i, Int3 p, HasLo&& hasLo, HasHi&& hasHi,
                 std::span<const Box> moved) {
  const double value = v[i];
  const bool nearer = std::any_of(moved.begin(), moved.end(),
                                  [&](const Box& b) { return squaredDistanceToCells(p, b) < value * value; });
  if (!nearer) return Shell::Kept;  // no moved cell is nearer than its value
  double grad[3];
  for (int a = 0; a < 3; ++a) {
    const std::size_t st = g.stride(a);
    grad[a] = hasLo(a) && hasHi(a) ? 0.5 * (double(v[i + st]) - double(v[i - st])) : 0.0;
  }
  const double len = std::sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2]);
  if (!(std::fabs(len - 1) <= kFootGradientTolerance)) return Shell::Reset;
  double foot[3];
  for (int a = 0; a < 3; ++a) foot[a] = p[a] - value * grad[a] / len;
  const bool nearMoved = std::any_of(moved.begin(), moved.end(), [&](const Box& b) {
    for (int a = 0; a < 3; ++a)
      if (foot[a] < b.lo[a] - 1 - kFootMargin || foot[a] > b.hi[a] + kFootMargin) return false;
    return true;
  });
  return nearMoved ? Shell::Reset : Shell::UpperBound;
}

// The dense passes over a tool's box visit ten to twenty times more voxels than its band, so
// they test 16 voxels per step. Both give exactly what their scalar loops give.

// Bit k set when |v[k]| != band (16 voxels).
std::uint32_t nearMask16(const float* v, float band) {
#if defined(__SSE2__)
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

// f[x] = base | (v[x] < 0 ? kNeg : 0) for x < n.
[[gnu::always_inline]] inline void signFlags(const float* v, std::uint8_t* f, int n, std::uint8_t base) {
  int x = 0;
#if defined(__SSE2__)
  const __m128 zero = _mm_setzero_ps();
  const __m128i neg = _mm_set1_epi8(char(kNeg)), b = _mm_set1_epi8(char(base));
  for (; x + 16 <= n; x += 16) {
    const __m128i m0 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x), zero));
    const __m128i m1 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 4), zero));
    const __m128i m2 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 8), zero));
    const __m128i m3 = _mm_castps_si128(_mm_cmplt_ps(_mm_loadu_ps(v + x + 12), zero));
    const __m128i bytes = _mm_packs_epi16(_mm_packs_epi32(m0, m1), _mm_packs_epi32(m2, m3));  // 0 or -1 each
    _mm_storeu_si128(reinterpret_cast<__m128i*>(f + x), _mm_or_si128(b, _mm_and_si128(bytes, neg)));
  }
#endif
  for (; x < n; ++x) f[x] = std::uint8_t(base | (v[x] < 0 ? kNeg : 0));
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
  std::vector<std::uint32_t> kept;
  std::vector<float> scaled;
  std::vector<std::uint32_t> farUnknown;
  std::vector<Box> nearMovedZ, nearMoved;  // scratch of the pass
};

struct Scratch {
  std::vector<std::uint8_t> flags;
  BandVoxels band;
  std::vector<ListPiece> pieces;
  std::vector<Box> resetBoxes, normalizeBoxes;
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

// Appends the voxels of row (y, z) of g in [lo, hi) (volume x) whose value is not +-band.
[[gnu::always_inline]] inline void collectRow(const DenseGrid& g, int lo, int hi, int y, int z, float band, BandVoxels& out) {
  const std::size_t row = g.index({lo, y, z});
  const float* v = g.v.data() + row;
  const int n = hi - lo;
  // Far voxels are the rule: test 16 at a time without a branch, then visit the others.
  int x = 0;
  for (; x + 16 <= n; x += 16) {
    std::uint32_t near = nearMask16(v + x, band);
    while (near) {
      const int k = __builtin_ctz(near);
      near &= near - 1;
      out.index.push_back(std::uint32_t(row + std::size_t(x + k)));
      out.point.push_back({lo + x + k, y, z});
    }
  }
  for (; x < n; ++x)
    if (std::fabs(v[x]) != band) {
      out.index.push_back(std::uint32_t(row + std::size_t(x)));
      out.point.push_back({lo + x, y, z});
    }
}

}  // namespace

void BandVoxels::collect(const DenseGrid& g, const Box& b, float band, const ProgressShare& progress) {
  box = b.intersect(g.box);
  index.clear();
  point.clear();
  for (int z = box.lo.z; z < box.hi.z; ++z) {
    progress.check();
    for (int y = box.lo.y; y < box.hi.y; ++y) collectRow(g, box.lo.x, box.hi.x, y, z, band, *this);
  }
  progress.advance(1);
}

void BandVoxels::collect(const DenseGrid& g, const Box& b, float band, const Volume& vol) {
  box = b.intersect(g.box);
  index.clear();
  point.clear();
  const Box stored = box.intersect(vol.domain());
  if (stored.empty()) return;
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
      for (const auto& [lo, hi] : row) collectRow(g, lo, hi, y, z, band, *this);
    }
}

MarchStats redistanceRegion(DenseGrid& g, const Box& region, float band, Outside outside,
                            const RedistanceOptions& options, ThreadPool& pool) {
  const ProgressShare& progress = options.progress;
  const Box r = region.intersect(g.box);
  if (r.empty()) return {};
  Scratch& s = scratch();
  s.flags.resize(g.v.size());
  std::uint8_t* flags = s.flags.data();
  float* v = g.v.data();
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
  const int exactSide = options.exactSide;
  const std::uint8_t exactNeg = exactSide < 0 ? kNeg : 0;

  // Every voxel: a source (or ignored) with its sign; interior = 2 voxels from every face.
  // Then, in the reset boxes, reset (unless on the side that is already exact), and in the
  // marked boxes marked, run by run of their union. Slab by slab of whole
  // z-slices: the grid of a small tool has short rows, and a slice is one run of the sign pass.
  const std::uint8_t base = outside == Outside::Source ? (kKnown | kFrozen) : (kIgnored | kFrozen);
  {
    const int sx = g.size.x, sy = g.size.y, sz = g.size.z;
    const int xLo = std::min(2, sx), xHi = std::max(xLo, sx - 2);
    const std::size_t slabs = std::size_t((sz + kSlabSlices - 1) / kSlabSlices);
    // A chunk of a whole-volume pass resets and normalizes its whole region, which spans each
    // row but the 2 voxels at either end (those without kInterior).
    const bool wholeRows = exactSide == 0 && reset.size() == 1 && reset[0] == r && marked.size() == 1 &&
                           marked[0] == r && r.lo.x == g.box.lo.x + xLo && r.hi.x == g.box.lo.x + xHi;
    forPieces(pool, parallel, slabs, [&](std::size_t slab) {
      const int z0 = int(slab) * kSlabSlices, z1 = std::min(sz, z0 + kSlabSlices);
      if (wholeRows) {
        // The bytes the passes below would give, in one pass per row: the 2 voxels at either
        // end as they are, the others reset, marked for normalizing, with kInterior on inner rows.
        for (int z = z0; z < z1; ++z) {
          progress.check();
          const int vz = g.box.lo.z + z;
          for (int y = 0; y < sy; ++y) {
            const std::size_t row = std::size_t(z) * g.sxy + std::size_t(y) * g.sx;
            const bool inner = z >= 2 && z + 2 < sz && y >= 2 && y + 2 < sy;
            const int vy = g.box.lo.y + y;
            if (vz >= r.lo.z && vz < r.hi.z && vy >= r.lo.y && vy < r.hi.y) {
              signFlags(v + row, flags + row, xLo, base);
              signFlags(v + row + xLo, flags + row + xLo, xHi - xLo,
                        std::uint8_t(kReset | kMarked | (inner ? kInterior : 0)));
              signFlags(v + row + xHi, flags + row + xHi, sx - xHi, base);
            } else {
              signFlags(v + row, flags + row, sx, base);
              if (inner)
                for (int x = xLo; x < xHi; ++x) flags[row + std::size_t(x)] |= kInterior;
            }
          }
        }
        return;
      }
      for (int z = z0; z < z1; ++z) {
        progress.check();
        const std::size_t slice = std::size_t(z) * g.sxy;
        const bool innerZ = z >= 2 && z + 2 < sz;
        signFlags(v + slice, flags + slice, int(g.sxy), innerZ ? std::uint8_t(base | kInterior) : base);
        if (!innerZ) continue;
        // The byte stores may alias anything a reference points at: the loops go through
        // pointers of their own so that they can be vectorized.
        constexpr std::uint8_t notInterior = std::uint8_t(~kInterior);
        for (int y = 0; y < sy; ++y) {
          std::uint8_t* const f = flags + slice + std::size_t(y) * g.sx;
          if (y < 2 || y + 2 >= sy) {
            for (int x = 0; x < sx; ++x) f[x] &= notInterior;
            continue;
          }
          for (int x = 0; x < xLo; ++x) f[x] &= notInterior;
          for (int x = xHi; x < sx; ++x) f[x] &= notInterior;
        }
      }
      // The x-runs of the union of `boxes` (sorted by lo.x) in each row of this slab, each once.
      std::vector<Box> slice;  // the boxes holding the current z, in the same order
      auto rows = [&](std::span<const Box> boxes, auto&& fn) {
        for (int z = g.box.lo.z + z0; z < g.box.lo.z + z1; ++z) {
          slice.clear();
          for (const Box& b : boxes)
            if (z >= b.lo.z && z < b.hi.z && b.lo.x < b.hi.x) slice.push_back(b);
          if (slice.empty()) continue;
          for (int y = g.box.lo.y; y < g.box.hi.y; ++y) {
            bool open = false;  // a run [lo, hi) is being merged
            int lo = 0, hi = 0;
            for (const Box& b : slice) {
              if (y < b.lo.y || y >= b.hi.y) continue;
              if (open && b.lo.x <= hi) {
                hi = std::max(hi, b.hi.x);
                continue;
              }
              if (open) fn(flags + g.index({lo, y, z}), hi - lo);
              open = true, lo = b.lo.x, hi = b.hi.x;
            }
            if (open) fn(flags + g.index({lo, y, z}), hi - lo);
          }
        }
      };
      if (exactSide == 0) {
        rows(reset, [](std::uint8_t* run, int n) {
          for (int x = 0; x < n; ++x) run[x] = std::uint8_t((run[x] & (kNeg | kInterior)) | kReset);
        });
      } else {
        rows(reset, [exactNeg](std::uint8_t* run, int n) {
          for (int x = 0; x < n; ++x) {
            const std::uint8_t keep = run[x] & (kNeg | kInterior);
            // On the side that is already exact a voxel stays; elsewhere it is reset unless kept.
            const bool exact = (keep & kNeg) == exactNeg;
            run[x] = std::uint8_t(keep | kReset | (exact ? (kKnown | kFrozen) : 0));
          }
        });
      }
      rows(marked, [](std::uint8_t* run, int n) {
        for (int x = 0; x < n; ++x) run[x] |= kMarked;
      });
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
  forPieces(pool, parallel, pieces, [&](std::size_t piece) {
    progress.check();
    ListPiece& out = s.pieces[piece];
    out.kept.clear();
    out.scaled.clear();
    out.farUnknown.clear();
    // The moved boxes that may matter to the list's current row (y, z): those whose cells lie
    // within band + kFootMargin of it on both axes (no voxel further from them can be nearer
    // than its value, inside them, or have its foot point near them). The list is in index
    // order, so its rows come one after the other.
    std::vector<Box>& nearZ = out.nearMovedZ;
    std::vector<Box>& near = out.nearMoved;
    const double reach = double(band) + kFootMargin;
    int rowY = std::numeric_limits<int>::min(), rowZ = rowY;
    auto cellDistance = [](int x, int lo, int hi) { return double(x < lo - 1 ? lo - 1 - x : std::max(0, x - hi)); };
    auto nearRow = [&](Int3 p) -> std::span<const Box> {
      if (p.z != rowZ) {
        rowZ = p.z, rowY = std::numeric_limits<int>::min();
        nearZ.clear();
        for (const Box& b : moved)
          if (cellDistance(p.z, b.lo.z, b.hi.z) < reach) nearZ.push_back(b);
      }
      if (p.y != rowY) {
        rowY = p.y;
        near.clear();
        for (const Box& b : nearZ) {
          const double dy = cellDistance(p.y, b.lo.y, b.hi.y), dz = cellDistance(p.z, b.lo.z, b.hi.z);
          if (dy * dy + dz * dz < reach * reach) near.push_back(b);
        }
      }
      return near;
    };
    const std::size_t end = std::min(list->index.size(), (piece + 1) * kListPiece);
    for (std::size_t k = piece * kListPiece; k < end; ++k) {
      const std::uint32_t i = list->index[k];
      const std::uint8_t f = flags[i];
      if ((f & (kReset | kFrozen)) != kReset) continue;  // a source, or ignored
      const float value = v[i];
      // Whether the voxel has a neighbour on each side of axis a: always, 2 voxels from every
      // face (the position is read only near the faces).
      const bool inner = f & kInterior;
      auto hasLo = [&](int a) { return inner || list->point[k][a] > g.box.lo[a]; };
      auto hasHi = [&](int a) { return inner || list->point[k][a] + 1 < g.box.hi[a]; };
      // Further than sqrt(3) from the surface: neither on it nor adjacent to it.
      bool adjacent = value == 0;  // on the surface itself (grid-aligned faces, edges, corners)
      if (!adjacent && std::fabs(value) < 1.75f) {
        const bool neg = value < 0;
        for (int a = 0; a < 3 && !adjacent; ++a) {
          const std::size_t st = g.stride(a);
          if (hasLo(a)) adjacent = (v[i - st] < 0) != neg;
          if (!adjacent && hasHi(a)) adjacent = (v[i + st] < 0) != neg;
        }
      }
      if (!adjacent) {
        if (!moved.empty()) {
          const Shell c = (f & kMarked) ? Shell::Reset
                                        : shellClass(g, v, i, list->point[k], hasLo, hasHi, nearRow(list->point[k]));
          if (c != Shell::Reset) {
            flags[i] = std::uint8_t(f | (c == Shell::Kept ? (kKnown | kFrozen) : kUpperBound));
            continue;
          }
        }
        out.farUnknown.push_back(i);
        continue;
      }
      flags[i] = std::uint8_t(f | kKnown | kFrozen);
      if (!normalizeKept || !(f & kMarked)) continue;
      double g2 = 0;
      for (int a = 0; a < 3; ++a) {
        const std::size_t st = g.stride(a);
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
        const std::size_t st = g.stride(a);
        if (hasLo(a) && (v[i - st] < 0) != (val < 0)) bound = std::min(bound, val / (val - v[i - st]));
        if (hasHi(a) && (v[i + st] < 0) != (val < 0)) bound = std::min(bound, val / (val - v[i + st]));
      }
      const double len = std::sqrt(g2);
      const double mag = len > 1e-6 ? std::min(std::fabs(val) / len, bound) : bound;
      out.kept.push_back(i);
      out.scaled.push_back(float(std::copysign(mag, val)));
    }
  });
  // The marcher starts every unknown voxel at +-band; those off the list are there already.
  forPieces(pool, parallel, pieces, [&](std::size_t piece) {
    const ListPiece& in = s.pieces[piece];
    for (std::size_t j = 0; j < in.kept.size(); ++j) v[in.kept[j]] = in.scaled[j];
    for (const std::uint32_t i : in.farUnknown) v[i] = v[i] < 0 ? -band : band;
  });
  progress.advance(kSetupShare);
  return fastMarchClassified(g, s.flags, list->index, band, options.order, pool, progress.part(1 - kSetupShare));
}

void redistanceVolume(Volume& vol, ThreadPool& pool) {
  const float band = vol.band();
  // Kept voxels need one neighbour, distances reach band + 1 voxels: a margin of band + 3.
  const int margin = int(std::ceil(band)) + 3;
  chunkedPass(vol, margin, pool, [&](DenseGrid& g, const Box&, ThreadPool&) {
    redistanceRegion(g, g.box.grown(-1), band, Outside::Ignored);
  });
}

}  // namespace marzipan
