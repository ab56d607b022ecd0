#include "fast_marching.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "thread_pool.hpp"

namespace marzipan {

namespace {

using namespace march_flag;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kBucketsPerVu = 32.0f;
constexpr float kMonotoneRun = 0.2f;  // see MarchOrder::Second
// Buckets between checks of the caller's progress: a bucket of a tool's region takes well
// under a millisecond.
constexpr std::size_t kBucketsPerCheck = 4;
// Fewer candidates than this (a small tool's band) are marched on the calling thread, one side
// after the other: waking a pool thread would cost about as much as the march itself.
constexpr std::size_t kParallelCandidates = std::size_t(1) << 13;

// Each side's own byte per voxel of the grid, built from the shared flags when the side starts:
// what the side may read there, in one load. The shared flags stay read-only while both sides
// run, and each side writes only its own array, so neither writes a byte the other reads.
constexpr std::uint8_t kUse = 1;     // a usable upwind value: a source or bound of this side, or reached
constexpr std::uint8_t kOpen = 2;    // an unknown voxel of this side: the march may lower it
constexpr std::uint8_t kOther = 4;   // a source of the other side: a second point with its sign
constexpr std::uint8_t kTaken = 8;   // taken from the queue at least once (for the retake count)
constexpr std::uint8_t kInside = kInterior;  // copied from the flags: no bounds checks needed

struct Entry {
  std::uint32_t index;
  float dist;
};
using Buckets = std::vector<std::vector<Entry>>;

// Solves sum_k c_k (u - m_k)^2 = 1 for the largest root, using the axes in increasing m and
// dropping those whose m is not below the root (Sethian's upwind rule). Spelled out for one,
// two and three axes with the values in registers: it runs once per update.
inline double solveEikonal(const double m[3], const double c[3], int n) {
  if (n == 1) return m[0] + (c[0] == 1.0 ? 1.0 : 2.0 / 3.0);  // 1 / sqrt(c): c is 1 or 9/4
  double m0 = m[0], m1 = m[1], m2 = n == 3 ? m[2] : 0.0, c0 = c[0], c1 = c[1], c2 = n == 3 ? c[2] : 0.0;
  // An insertion sort (stable for equal m).
  if (m1 < m0) std::swap(m0, m1), std::swap(c0, c1);
  if (n == 3 && m2 < m1) {
    std::swap(m1, m2), std::swap(c1, c2);
    if (m1 < m0) std::swap(m0, m1), std::swap(c0, c1);
  }
  double a = c0, b = c0 * m0, cc = c0 * m0 * m0;
  double u = m0 + (c0 == 1.0 ? 1.0 : 2.0 / 3.0);
  // Adds the next axis while its m is below the root; false when the sum stops there.
  auto add = [&](double mk, double ck) {
    if (!(u > mk)) return false;
    const double a2 = a + ck, b2 = b + ck * mk, c2k = cc + ck * mk * mk;
    const double disc = b2 * b2 - a2 * (c2k - 1.0);
    if (disc < 0) return false;
    a = a2, b = b2, cc = c2k;
    u = (b + std::sqrt(disc)) / a;
    return true;
  };
  if (add(m1, c1) && n == 3) add(m2, c2);
  return u;
}

// One side of the surface. It reads its own state array, the values of its own side and of
// the other side's sources, and writes only its own side's unknown voxels and its state array:
// the two sides may run at the same time on one grid.
class SideMarcher {
 public:
  SideMarcher(DenseGrid& g, const std::uint8_t* flags, std::vector<std::uint8_t>& state, float band, bool second,
              std::uint8_t negBit, Buckets& buckets)
      : g_(g), v_(g.v.data()), band_(band), second_(second), negBit_(negBit), buckets_(buckets) {
    stride_[0] = 1, stride_[1] = g.sx, stride_[2] = g.sxy;
    buckets_.resize(std::size_t(std::ceil(band * kBucketsPerVu)) + 1);
    for (auto& b : buckets_) b.clear();
    // 16 bytes per step: the grid is the gathered box, the band only a few percent of it.
    state.resize(g.v.size());
    st_ = state.data();
    std::size_t i = 0;
    const std::size_t n = state.size();
#if defined(__SSE2__)
    const __m128i negMask = _mm_set1_epi8(char(kNeg)), sideNeg = _mm_set1_epi8(char(negBit));
    const __m128i usableMask = _mm_set1_epi8(char(kKnown | kIgnored)), known = _mm_set1_epi8(char(kKnown));
    const __m128i frozen = _mm_set1_epi8(char(kFrozen)), zero = _mm_setzero_si128();
    const __m128i interior = _mm_set1_epi8(char(kInterior)), use = _mm_set1_epi8(char(kUse));
    const __m128i open = _mm_set1_epi8(char(kOpen)), other = _mm_set1_epi8(char(kOther));
    const __m128i upper = _mm_set1_epi8(char(kUpperBound));
    for (; i + 16 <= n; i += 16) {
      const __m128i f = _mm_loadu_si128(reinterpret_cast<const __m128i*>(flags + i));
      const __m128i own = _mm_cmpeq_epi8(_mm_and_si128(f, negMask), sideNeg);
      const __m128i usable = _mm_cmpeq_epi8(_mm_and_si128(f, usableMask), known);
      const __m128i unfrozen = _mm_cmpeq_epi8(_mm_and_si128(f, frozen), zero);
      const __m128i bound = _mm_cmpeq_epi8(_mm_and_si128(f, upper), upper);
      __m128i st = _mm_and_si128(f, interior);
      st = _mm_or_si128(st, _mm_and_si128(_mm_and_si128(own, _mm_or_si128(usable, bound)), use));
      st = _mm_or_si128(st, _mm_and_si128(_mm_and_si128(own, unfrozen), open));
      st = _mm_or_si128(st, _mm_and_si128(_mm_andnot_si128(own, usable), other));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(st_ + i), st);
    }
#endif
    for (; i < n; ++i) {
      const std::uint8_t f = flags[i];
      const bool own = (f & kNeg) == negBit, usable = (f & (kKnown | kIgnored)) == kKnown;
      const bool bound = f & kUpperBound;
      st_[i] = std::uint8_t((f & kInterior) | (own && (usable || bound) ? kUse : 0) |
                            (own && !(f & kFrozen) ? kOpen : 0) | (!own && usable ? kOther : 0));
    }
  }

  // progress: this side's share, advanced as its buckets are taken.
  MarchStats run(std::span<const std::uint32_t> seeds, const ProgressShare& progress) {
    for (const std::uint32_t i : seeds) push(i, mag(i), 0);
    const double perBucket = 1.0 / double(buckets_.size());
    for (std::size_t b = 0; b < buckets_.size(); ++b) {
      if (b % kBucketsPerCheck == 0) {
        progress.check();
        if (b > 0) progress.advance(kBucketsPerCheck * perBucket);
      }
      current_ = b;
      auto& bucket = buckets_[b];
      for (std::size_t k = 0; k < bucket.size(); ++k) {
        const Entry e = bucket[k];
        if (e.dist != mag(e.index)) continue;  // superseded by a lower entry
        ++stats_.accepted;
        if (st_[e.index] & kTaken) ++stats_.retaken;
        st_[e.index] |= kUse | kTaken;
        // A neighbour already at or below this value would drop it from its stencil (the
        // upwind rule), so this voxel cannot lower it. About half of the visits update nothing:
        // the others are listed first and updated after, in the same order, by one inlined copy
        // of the interior update (an update writes only its own voxel, which no other visit reads).
        std::size_t todo[6];
        int count = 0;
        auto visit = [&](std::size_t n) __attribute__((always_inline)) {
          todo[count] = n;
          count += (st_[n] & kOpen) && mag(n) > e.dist;
        };
        if (st_[e.index] & kInside) {
          for (int a = 0; a < 3; ++a) visit(e.index - stride_[a]), visit(e.index + stride_[a]);
        } else {
          const Int3 p = g_.point(e.index) - g_.box.lo;
          for (int a = 0; a < 3; ++a) {
            if (p[a] > 0) visit(e.index - stride_[a]);
            if (p[a] + 1 < g_.size[a]) visit(e.index + stride_[a]);
          }
        }
        for (int t = 0; t < count; ++t) {
          if (st_[todo[t]] & kInside) {
            updateAt<true>(todo[t]);
          } else {
            updateBorder(todo[t]);
          }
        }
      }
      bucket.clear();
    }
    progress.advance(double(buckets_.size() - (buckets_.size() - 1) / kBucketsPerCheck * kBucketsPerCheck) * perBucket);
    return stats_;
  }

  // Sources (and upper bounds) of this side that border one of its unknown voxels other than
  // upper bounds: only these can lower anything. An upper bound is lowered only by the part of
  // the surface that moved, which reaches it through the other unknown voxels.
  static bool feeds(const DenseGrid& g, const std::uint8_t* flags, std::size_t i) {
    const std::uint8_t side = flags[i] & kNeg;
    const std::size_t stride[3] = {1, g.sx, g.sxy};
    auto open = [&](std::size_t n) { return (flags[n] & (kFrozen | kNeg | kUpperBound)) == side; };
    if (flags[i] & kInterior) {
      for (int a = 0; a < 3; ++a)
        if (open(i - stride[a]) || open(i + stride[a])) return true;
      return false;
    }
    const Int3 p = g.point(i) - g.box.lo;
    for (int a = 0; a < 3; ++a) {
      if (p[a] > 0 && open(i - stride[a])) return true;
      if (p[a] + 1 < g.size[a] && open(i + stride[a])) return true;
    }
    return false;
  }

 private:
  float mag(std::size_t i) const { return std::fabs(v_[i]); }

  void push(std::size_t i, float d, std::size_t minBucket) {
    const std::size_t b = std::max(minBucket, std::size_t(d * kBucketsPerVu));
    buckets_[std::min(b, buckets_.size() - 1)].push_back({std::uint32_t(i), d});
  }

  // The second upwind value two steps away along one axis, or infinity. The signed field is
  // smooth across the surface, so a source of the other sign serves with its sign: without
  // it the first layer off the surface is only first order, and its bias shows in every
  // curvature.
  double secondUpwind(std::size_t n2) const {
    const std::uint8_t s = st_[n2];
    if (s & kUse) return mag(n2);
    return (s & kOther) ? -double(mag(n2)) : kInf;
  }

  [[gnu::noinline]] void updateBorder(std::size_t n) { updateAt<false>(n); }

  // Recomputes voxel n (unknown, this side) from its known neighbours. Inside: n is at least 2
  // voxels from every face of the grid, so no neighbour needs a bounds check.
  template <bool Inside>
  [[gnu::always_inline]] inline void updateAt(std::size_t n) {
    Int3 q{};
    if constexpr (!Inside) q = g_.point(n) - g_.box.lo;
    double m[3], c[3];
    int count = 0;
    for (int a = 0; a < 3; ++a) {
      const std::size_t s = stride_[a];
      const bool hasLo = Inside || q[a] > 0, hasHi = Inside || q[a] + 1 < g_.size[a];
      float best = kInf;
      int dir = 0;
      if (hasLo && (st_[n - s] & kUse)) best = mag(n - s), dir = -1;
      if (hasHi && (st_[n + s] & kUse) && mag(n + s) < best) best = mag(n + s), dir = +1;
      if (dir == 0) continue;
      m[count] = best;
      c[count] = 1.0;
      if (second_ && (Inside || (q[a] + 2 * dir >= 0 && q[a] + 2 * dir < g_.size[a]))) {
        const double b = secondUpwind(dir > 0 ? n + 2 * s : n - 2 * s);
        if (best - b >= kMonotoneRun) {
          m[count] = (4.0 * best - b) / 3.0;
          c[count] = 9.0 / 4.0;
        }
      }
      ++count;
    }
    if (count == 0) return;
    const float u = float(solveEikonal(m, c, count));  // compared as stored, or a root rounded
    if (u < mag(n) && u < band_) {                      // up would be pushed again forever
      v_[n] = negBit_ ? -u : u;
      push(n, u, current_);
    }
  }

  DenseGrid& g_;
  float* v_;
  std::uint8_t* st_ = nullptr;
  float band_;
  bool second_;
  std::uint8_t negBit_;
  Buckets& buckets_;
  std::size_t stride_[3];
  std::size_t current_ = 0;
  MarchStats stats_;
};

// Per-thread scratch, reused across calls: tools march thousands of times, and fresh
// multi-megabyte arrays each time cost as much in page faults as the marching itself.
struct Scratch {
  std::vector<std::uint8_t> flags;    // fastMarch's classification
  std::vector<std::uint8_t> state[2];  // each side's own (SideMarcher)
  std::vector<std::uint32_t> candidates;
  std::vector<std::uint32_t> seeds[2];
  Buckets buckets[2];
};
Scratch& scratch() {
  thread_local Scratch s;
  return s;
}

}  // namespace

MarchStats fastMarchClassified(DenseGrid& g, const std::vector<std::uint8_t>& flags,
                               std::span<const std::uint32_t> candidates, float band, MarchOrder order,
                               ThreadPool& pool, ProgressShare progress) {
  Scratch& s = scratch();
  const std::uint8_t* f = flags.data();
  const bool second = order == MarchOrder::Second;
  MarchStats side[2];
  auto seed = [&](std::uint32_t i) {
    return ((f[i] & (kKnown | kIgnored)) == kKnown || (f[i] & kUpperBound)) && std::fabs(g.v[i]) < band &&
           SideMarcher::feeds(g, f, i);
  };
  auto march = [&](std::size_t k) {
    SideMarcher m(g, f, s.state[k], band, second, k ? kNeg : 0, s.buckets[k]);
    side[k] = m.run(s.seeds[k], progress.part(0.5));
  };
  if (pool.threads() > 1 && candidates.size() >= kParallelCandidates) {
    // Each side picks its own seeds, so that neither waits for the other.
    pool.parallelFor(2, [&](std::size_t k) {
      const std::uint8_t negBit = k ? kNeg : 0;
      s.seeds[k].clear();
      for (const std::uint32_t i : candidates)
        if ((f[i] & kNeg) == negBit && seed(i)) s.seeds[k].push_back(i);
      march(k);
    });
  } else {
    for (auto& seeds : s.seeds) seeds.clear();
    for (const std::uint32_t i : candidates)
      if (seed(i)) s.seeds[(f[i] & kNeg) ? 1 : 0].push_back(i);
    march(0);
    march(1);
  }
  return {side[0].accepted + side[1].accepted, side[0].retaken + side[1].retaken};
}

MarchStats fastMarch(DenseGrid& g, const std::vector<MarchState>& state, float band, MarchOrder order) {
  Scratch& s = scratch();
  s.flags.resize(g.v.size());
  s.candidates.clear();
  float* v = g.v.data();
  std::uint8_t* flags = s.flags.data();
  const int sx = g.size.x, sy = g.size.y, sz = g.size.z;
  const int xLo = std::min(2, sx), xHi = std::max(xLo, sx - 2);  // interior columns [xLo, xHi)
  std::size_t row = 0;
  for (int z = 0; z < sz; ++z)
    for (int y = 0; y < sy; ++y, row += std::size_t(sx)) {
      const std::uint8_t inner = z >= 2 && z + 2 < sz && y >= 2 && y + 2 < sy ? kInterior : 0;
      for (int x = 0; x < sx; ++x) {
        const std::size_t i = row + std::size_t(x);
        const std::uint8_t st = std::uint8_t(state[i]);
        const bool neg = v[i] < 0;
        flags[i] = std::uint8_t(st | (neg ? kNeg : 0) | (x >= xLo && x < xHi ? inner : 0));
        if (state[i] == MarchState::Unknown) {
          v[i] = neg ? -band : band;
        } else if (state[i] == MarchState::Source && std::fabs(v[i]) < band) {
          s.candidates.push_back(std::uint32_t(i));
        }
      }
    }
  return fastMarchClassified(g, s.flags, s.candidates, band, order, ThreadPool::serial());
}

}  // namespace marzipan
