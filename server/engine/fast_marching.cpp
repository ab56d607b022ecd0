#include "fast_marching.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace marzipan {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kBucketsPerVu = 32.0f;
constexpr float kMonotoneRun = 0.2f;  // see MarchOrder::Second

struct Entry {
  std::uint32_t index;
  float dist;
};

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

class Marcher {
 public:
  Marcher(DenseGrid& g, const std::vector<MarchState>& state, float band, MarchOrder order)
      : g_(g), band_(band), second_(order == MarchOrder::Second) {
    const std::size_t n = g.v.size();
    dist_.resize(n);
    flag_.resize(n);
    stride_[0] = 1, stride_[1] = g.sx, stride_[2] = g.sxy;
    seeds_.clear();
    written_.clear();
    // Locals, not members: stores to the byte-typed flags may alias anything, and would make
    // the compiler reload every member and vector pointer once per voxel.
    const float* v = g.v.data();
    const MarchState* states = state.data();
    std::uint8_t* flags = flag_.data();
    float* dist = dist_.data();
    const int sx = g.size.x, sy = g.size.y, sz = g.size.z;
    auto init = [&](std::size_t i, std::uint8_t position) {
      // MarchState's values are its flag bits (Source = known + frozen, Ignored = ignored +
      // frozen), so the flags are the state plus sign and position bits.
      const std::uint8_t st = std::uint8_t(states[i]);
      flags[i] = std::uint8_t(st | position | (v[i] < 0 ? kNeg : 0));
      const float mag = std::fabs(v[i]);
      if (st == std::uint8_t(MarchState::Source)) {
        dist[i] = mag;
        if (mag < band) seeds_.push_back(std::uint32_t(i));  // only these can lower anything
      } else {
        dist[i] = kInf;
        // Every unknown voxel not already at +-band must be written even if the march never
        // reaches it (it becomes +-band); one at +-band stays as it is unless reached.
        if (st == std::uint8_t(MarchState::Unknown) && mag != band) written_.push_back(std::uint32_t(i));
      }
    };
    const int xLo = std::min(2, sx), xHi = std::max(xLo, sx - 2);  // interior columns [xLo, xHi)
    std::size_t row = 0;
    for (int z = 0; z < sz; ++z)
      for (int y = 0; y < sy; ++y, row += std::size_t(sx)) {
        const std::uint8_t inner = z >= 2 && z + 2 < sz && y >= 2 && y + 2 < sy ? kInterior : 0;
        for (int x = 0; x < xLo; ++x) init(row + std::size_t(x), 0);
        for (int x = xLo; x < xHi; ++x) init(row + std::size_t(x), inner);
        for (int x = xHi; x < sx; ++x) init(row + std::size_t(x), 0);
      }
    buckets_.resize(std::size_t(std::ceil(band * kBucketsPerVu)) + 1);
  }

  MarchStats run() {
    // Only band sources next to an unknown voxel can lower anything.
    for (const std::uint32_t i : seeds_) {
      bool feeds = false;
      forNeighbours(i, [&](std::size_t n) { feeds = feeds || !(flag_[n] & kFrozen); });
      if (feeds) push(i, dist_[i], 0);
    }
    for (std::size_t b = 0; b < buckets_.size(); ++b) {
      current_ = b;
      auto& bucket = buckets_[b];
      for (std::size_t k = 0; k < bucket.size(); ++k) {
        const Entry e = bucket[k];
        if (e.dist != dist_[e.index]) continue;  // superseded by a lower entry
        ++stats_.accepted;
        if (flag_[e.index] & kTaken) ++stats_.retaken;
        flag_[e.index] |= kKnown | kTaken;
        // A neighbour already at or below this value would drop it from its stencil (the
        // upwind rule), so this voxel cannot lower it.
        forNeighbours(e.index, [&](std::size_t n) {
          if (!(flag_[n] & kFrozen) && dist_[n] > e.dist) update(n);
        });
      }
      bucket.clear();
    }
    for (const std::uint32_t i : written_) g_.v[i] = (flag_[i] & kNeg) ? -std::min(dist_[i], band_) : std::min(dist_[i], band_);
    return stats_;
  }

 private:
  static constexpr std::uint8_t kKnown = 1;     // has a value others may use (source or taken)
  static constexpr std::uint8_t kNeg = 2;       // inside
  static constexpr std::uint8_t kFrozen = 4;    // source or ignored: never recomputed
  static constexpr std::uint8_t kIgnored = 8;
  static constexpr std::uint8_t kInterior = 16; // at least 2 voxels from every face of the grid
  static_assert(std::uint8_t(MarchState::Source) == (kKnown | kFrozen) &&
                std::uint8_t(MarchState::Ignored) == (kIgnored | kFrozen));
  static constexpr std::uint8_t kTaken = 32;    // taken from the queue at least once

  Int3 coords(std::size_t i) const {
    return {int(i % g_.sx), int((i / g_.sx) % std::size_t(g_.size.y)), int(i / g_.sxy)};
  }

  template <class F>
  void forNeighbours(std::size_t i, F&& fn) const {
    if (flag_[i] & kInterior) {
      for (int a = 0; a < 3; ++a) fn(i - stride_[a]), fn(i + stride_[a]);
      return;
    }
    const Int3 p = coords(i);
    for (int a = 0; a < 3; ++a) {
      if (p[a] > 0) fn(i - stride_[a]);
      if (p[a] + 1 < g_.size[a]) fn(i + stride_[a]);
    }
  }

  void push(std::size_t i, float d, std::size_t minBucket) {
    const std::size_t b = std::max(minBucket, std::size_t(d * kBucketsPerVu));
    buckets_[std::min(b, buckets_.size() - 1)].push_back({std::uint32_t(i), d});
  }

  // Usable as an upwind value for a voxel whose sign bit is negBit.
  bool usable(std::size_t n, std::uint8_t negBit) const {
    return (flag_[n] & (kKnown | kIgnored | kNeg)) == (kKnown | negBit);
  }

  // The second upwind value two steps away along one axis, or infinity. The signed field is
  // smooth across the surface, so a source of the other sign serves with its sign: without
  // it the first layer off the surface is only first order, and its bias shows in every
  // curvature.
  double secondUpwind(std::size_t n2, std::uint8_t negBit) const {
    const std::uint8_t f = flag_[n2];
    if ((f & (kKnown | kIgnored)) != kKnown) return kInf;
    if ((f & kNeg) == negBit) return dist_[n2];
    return (f & kFrozen) ? -double(dist_[n2]) : kInf;
  }

  // Recomputes voxel n from its known neighbours.
  void update(std::size_t n) {
    const std::uint8_t negBit = flag_[n] & kNeg;
    const bool interior = flag_[n] & kInterior;
    Int3 q{};
    if (!interior) q = coords(n);
    double m[3], c[3];
    int count = 0;
    for (int a = 0; a < 3; ++a) {
      const std::size_t s = stride_[a];
      const bool hasLo = interior || q[a] > 0, hasHi = interior || q[a] + 1 < g_.size[a];
      float best = kInf;
      int dir = 0;
      if (hasLo && usable(n - s, negBit)) best = dist_[n - s], dir = -1;
      if (hasHi && usable(n + s, negBit) && dist_[n + s] < best) best = dist_[n + s], dir = +1;
      if (dir == 0) continue;
      m[count] = best;
      c[count] = 1.0;
      if (second_ && (interior || (q[a] + 2 * dir >= 0 && q[a] + 2 * dir < g_.size[a]))) {
        const double b = secondUpwind(dir > 0 ? n + 2 * s : n - 2 * s, negBit);
        if (best - b >= kMonotoneRun) {
          m[count] = (4.0 * best - b) / 3.0;
          c[count] = 9.0 / 4.0;
        }
      }
      ++count;
    }
    if (count == 0) return;
    const float u = float(solveEikonal(m, c, count));  // compared as stored, or a root rounded
    if (u < dist_[n] && u < band_) {                    // up would be pushed again forever
      if (dist_[n] == kInf) written_.push_back(std::uint32_t(n));
      dist_[n] = u;
      push(n, u, current_);
    }
  }

  DenseGrid& g_;
  float band_;
  bool second_;
  std::size_t stride_[3];
  // Per-thread scratch, reused across calls: global operations march thousands of times, and
  // fresh multi-megabyte arrays each time cost as much in page faults as the marching itself.
  struct Scratch {
    std::vector<float> dist;
    std::vector<std::uint8_t> flag;
    std::vector<std::vector<Entry>> buckets;
    std::vector<std::uint32_t> seeds;    // sources inside the band
    std::vector<std::uint32_t> written;  // unknown voxels that were in the band or were reached
  };
  static Scratch& scratch() {
    thread_local Scratch s;
    return s;
  }
  std::vector<float>& dist_ = scratch().dist;
  std::vector<std::uint8_t>& flag_ = scratch().flag;
  std::vector<std::vector<Entry>>& buckets_ = scratch().buckets;
  std::vector<std::uint32_t>& seeds_ = scratch().seeds;
  std::vector<std::uint32_t>& written_ = scratch().written;
  std::size_t current_ = 0;
  MarchStats stats_;
};

}  // namespace

MarchStats fastMarch(DenseGrid& grid, const std::vector<MarchState>& state, float band, MarchOrder order) {
  return Marcher(grid, state, band, order).run();
}

}  // namespace marzipan
