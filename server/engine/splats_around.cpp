// The bricks whose splats a change can touch (splats.hpp, bricksAroundChanges): a changed brick
// or a face neighbour with a voxel next to the surface, before or after, whose own value or a
// 6-neighbour's changed. Worked out on the slices' words of splat_slices.hpp, of both states
// (before and after the changes), only for the bricks and slices the test reaches.
#include "splats.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <tuple>
#include <vector>

#include "splat_slices.hpp"

namespace marzipan {

namespace {

using namespace splat_slices;

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
