#include "fast_marching.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

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

// Bits of the per-side array of voxels the march made known (the shared flags stay read-only
// while both sides run, so neither side writes a byte the other reads).
constexpr std::uint8_t kReached = 1;  // taken from the queue: its value may be used
constexpr std::uint8_t kTaken = 2;    // taken at least once (for the retake count)

struct Entry {
  std::uint32_t index;
  float dist;
};
using Buckets = std::vector<std::vector<Entry>>;

// Solves sum_k c_k (u - m_k)^2 = 1 for the largest root, using the axes in increasing m and
// dropping those whose m is not below the root (Sethian's upwind rule).
double solveEikonal(double m[3], double c[3], int n) {
  for (int i = 1; i < n; ++i)  // insertion sort of at most three
    for (int j = i; j > 0 && m[j] < m[j - 1]; --j) std::swap(m[j], m[j - 1]), std::swap(c[j], c[j - 1]);
  double a = c[0], b = c[0] * m[0], cc = c[0] * m[0] * m[0];
  double u = m[0] + (c[0] == 1.0 ? 1.0 : 2.0 / 3.0);  // 1 / sqrt(c): c is 1 or 9/4
  for (int k = 1; k < n && u > m[k]; ++k) {
    const double a2 = a + c[k], b2 = b + c[k] * m[k], c2 = cc + c[k] * m[k] * m[k];
    const double disc = b2 * b2 - a2 * (c2 - 1.0);
    if (disc < 0) break;
    a = a2, b = b2, cc = c2;
    u = (b + std::sqrt(disc)) / a;
  }
  return u;
}

// One side of the surface. It reads the shared flags, the values of its own side and of the
// other side's sources, and writes only its own side's unknown voxels and `reached` bytes:
// the two sides may run at the same time on one grid.
class SideMarcher {
 public:
  SideMarcher(DenseGrid& g, const std::uint8_t* flags, std::uint8_t* reached, float band, bool second,
              std::uint8_t negBit, Buckets& buckets)
      : g_(g), v_(g.v.data()), flags_(flags), reached_(reached), band_(band), second_(second), negBit_(negBit),
        buckets_(buckets) {
    stride_[0] = 1, stride_[1] = g.sx, stride_[2] = g.sxy;
    buckets_.resize(std::size_t(std::ceil(band * kBucketsPerVu)) + 1);
    for (auto& b : buckets_) b.clear();
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
        if (reached_[e.index] & kTaken) ++stats_.retaken;
        reached_[e.index] |= kReached | kTaken;
        // A neighbour already at or below this value would drop it from its stencil (the
        // upwind rule), so this voxel cannot lower it.
        forNeighbours(e.index, [&](std::size_t n) {
          if ((flags_[n] & (kFrozen | kNeg)) == negBit_ && mag(n) > e.dist) update(n);
        });
      }
      bucket.clear();
    }
    progress.advance(double(buckets_.size() - (buckets_.size() - 1) / kBucketsPerCheck * kBucketsPerCheck) * perBucket);
    return stats_;
  }

  // Sources of this side that border one of its unknown voxels: only these can lower anything.
  static bool feeds(const DenseGrid& g, const std::uint8_t* flags, std::size_t i) {
    const std::uint8_t side = flags[i] & kNeg;
    bool any = false;
    forEachNeighbour(g, flags, i, [&](std::size_t n) { any = any || (flags[n] & (kFrozen | kNeg)) == side; });
    return any;
  }

 private:
  float mag(std::size_t i) const { return std::fabs(v_[i]); }

  template <class F>
  static void forEachNeighbour(const DenseGrid& g, const std::uint8_t* flags, std::size_t i, F&& fn) {
    const std::size_t stride[3] = {1, g.sx, g.sxy};
    if (flags[i] & kInterior) {
      for (int a = 0; a < 3; ++a) fn(i - stride[a]), fn(i + stride[a]);
      return;
    }
    const Int3 p = g.point(i) - g.box.lo;
    for (int a = 0; a < 3; ++a) {
      if (p[a] > 0) fn(i - stride[a]);
      if (p[a] + 1 < g.size[a]) fn(i + stride[a]);
    }
  }
  template <class F>
  void forNeighbours(std::size_t i, F&& fn) const {
    forEachNeighbour(g_, flags_, i, fn);
  }

  void push(std::size_t i, float d, std::size_t minBucket) {
    const std::size_t b = std::max(minBucket, std::size_t(d * kBucketsPerVu));
    buckets_[std::min(b, buckets_.size() - 1)].push_back({std::uint32_t(i), d});
  }

  // The second upwind value two steps away along one axis, or infinity. The signed field is
  // smooth across the surface, so a source of the other sign serves with its sign: without
  // it the first layer off the surface is only first order, and its bias shows in every
  // curvature.
  double secondUpwind(std::size_t n2) const {
    const std::uint8_t f = flags_[n2];
    if (f & kIgnored) return kInf;
    if ((f & kNeg) == negBit_) return ((f & kKnown) || (reached_[n2] & kReached)) ? mag(n2) : kInf;
    return (f & kKnown) ? -double(mag(n2)) : kInf;
  }

  // Usable as an upwind value: known, on this side.
  bool usable(std::size_t n) const {
    const std::uint8_t f = flags_[n];
    if ((f & (kIgnored | kNeg)) != negBit_) return false;
    return (f & kKnown) || (reached_[n] & kReached);
  }

  // Recomputes voxel n (unknown, this side) from its known neighbours.
  void update(std::size_t n) {
    const bool interior = flags_[n] & kInterior;
    Int3 q{};
    if (!interior) q = g_.point(n) - g_.box.lo;
    double m[3], c[3];
    int count = 0;
    for (int a = 0; a < 3; ++a) {
      const std::size_t s = stride_[a];
      const bool hasLo = interior || q[a] > 0, hasHi = interior || q[a] + 1 < g_.size[a];
      float best = kInf;
      int dir = 0;
      if (hasLo && usable(n - s)) best = mag(n - s), dir = -1;
      if (hasHi && usable(n + s) && mag(n + s) < best) best = mag(n + s), dir = +1;
      if (dir == 0) continue;
      m[count] = best;
      c[count] = 1.0;
      if (second_ && (interior || (q[a] + 2 * dir >= 0 && q[a] + 2 * dir < g_.size[a]))) {
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
  const std::uint8_t* flags_;
  std::uint8_t* reached_;
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
  std::vector<std::uint8_t> reached;  // per voxel, kReached | kTaken (each side its own voxels)
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
  s.reached.resize(g.v.size());
  std::memset(s.reached.data(), 0, s.reached.size());
  for (auto& seeds : s.seeds) seeds.clear();
  const std::uint8_t* f = flags.data();
  for (const std::uint32_t i : candidates) {
    if ((f[i] & (kKnown | kIgnored)) != kKnown || !(std::fabs(g.v[i]) < band)) continue;
    if (SideMarcher::feeds(g, f, i)) s.seeds[(f[i] & kNeg) ? 1 : 0].push_back(i);
  }
  const bool second = order == MarchOrder::Second;
  MarchStats side[2];
  auto runSide = [&](std::size_t k) {
    SideMarcher m(g, f, s.reached.data(), band, second, k ? kNeg : 0, s.buckets[k]);
    side[k] = m.run(s.seeds[k], progress.part(0.5));
  };
  if (pool.threads() > 1 && !s.seeds[0].empty() && !s.seeds[1].empty()) {
    pool.parallelFor(2, runSide);
  } else {
    runSide(0);
    runSide(1);
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
