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
  double u = m[0] + 1.0 / std::sqrt(c[0]);
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
      : g_(g), state_(state), band_(band), second_(order == MarchOrder::Second) {
    const std::size_t n = g.v.size();
    dist_.resize(n);
    known_.assign(n, 0);
    neg_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      neg_[i] = g.v[i] < 0;
      if (state[i] == MarchState::Source) {
        dist_[i] = std::fabs(g.v[i]);
        known_[i] = 1;
      } else {
        dist_[i] = kInf;
      }
    }
    buckets_.resize(std::size_t(std::ceil(band * kBucketsPerVu)) + 1);
  }

  MarchStats run() {
    for (std::size_t i = 0; i < dist_.size(); ++i)
      if (state_[i] == MarchState::Source && dist_[i] < band_) push(i, dist_[i], 0);
    for (std::size_t b = 0; b < buckets_.size(); ++b) {
      current_ = b;
      auto& bucket = buckets_[b];
      for (std::size_t k = 0; k < bucket.size(); ++k) {
        const Entry e = bucket[k];
        if (e.dist != dist_[e.index]) continue;  // superseded by a lower entry
        ++stats_.accepted;
        if (known_[e.index] == 2) ++stats_.retaken;
        if (known_[e.index] == 0) known_[e.index] = 2;
        relax(e.index);
      }
      bucket.clear();
      bucket.shrink_to_fit();
    }
    for (std::size_t i = 0; i < dist_.size(); ++i)
      if (state_[i] == MarchState::Unknown) g_.v[i] = neg_[i] ? -std::min(dist_[i], band_) : std::min(dist_[i], band_);
    return stats_;
  }

 private:
  void push(std::size_t i, float d, std::size_t minBucket) {
    const std::size_t b = std::max(minBucket, std::size_t(d * kBucketsPerVu));
    buckets_[std::min(b, buckets_.size() - 1)].push_back({std::uint32_t(i), d});
  }

  bool usable(std::size_t n, bool neg) const {
    return known_[n] != 0 && neg_[n] == neg && state_[n] != MarchState::Ignored;
  }

  // Recomputes the Unknown neighbours of voxel i from their known neighbours.
  void relax(std::size_t i) {
    const Int3 p{int(i % g_.sx), int((i / g_.sx) % std::size_t(g_.size.y)), int(i / g_.sxy)};
    for (int axis = 0; axis < 3; ++axis) {
      const std::size_t s = g_.stride(axis);
      if (p[axis] > 0) update(i - s, p, axis, -1);
      if (p[axis] + 1 < g_.size[axis]) update(i + s, p, axis, +1);
    }
  }

  // n is the neighbour of the voxel at p along `axis` in direction `dir`.
  void update(std::size_t n, Int3 p, int axis, int dir) {
    if (state_[n] != MarchState::Unknown) return;
    Int3 q = p;
    q[axis] += dir;
    const bool neg = neg_[n];
    double m[3], c[3];
    int count = 0;
    for (int a = 0; a < 3; ++a) {
      const std::size_t s = g_.stride(a);
      float best = kInf;
      int bestDir = 0;
      if (q[a] > 0 && usable(n - s, neg)) best = dist_[n - s], bestDir = -1;
      if (q[a] + 1 < g_.size[a] && usable(n + s, neg) && dist_[n + s] < best) best = dist_[n + s], bestDir = +1;
      if (bestDir == 0) continue;
      m[count] = best;
      c[count] = 1.0;
      const int q2 = q[a] + 2 * bestDir;
      if (second_ && q2 >= 0 && q2 < g_.size[a]) {
        const std::size_t n2 = bestDir > 0 ? n + 2 * s : n - 2 * s;
        // The signed field is smooth across the surface, so a kept voxel of the other sign
        // serves as the second upwind point with its sign: without it the first layer off
        // the surface is only first order, and its bias shows in every curvature.
        double b = kInf;
        if (usable(n2, neg)) {
          b = dist_[n2];
        } else if (state_[n2] == MarchState::Source && neg_[n2] != neg) {
          b = -double(dist_[n2]);
        }
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
      dist_[n] = u;
      push(n, u, current_);
    }
  }

  DenseGrid& g_;
  const std::vector<MarchState>& state_;
  float band_;
  bool second_;
  std::vector<float> dist_;
  std::vector<std::uint8_t> known_;  // 0 not yet, 1 source, 2 taken from the queue
  std::vector<std::uint8_t> neg_;
  std::vector<std::vector<Entry>> buckets_;
  std::size_t current_ = 0;
  MarchStats stats_;
};

}  // namespace

MarchStats fastMarch(DenseGrid& grid, const std::vector<MarchState>& state, float band, MarchOrder order) {
  return Marcher(grid, state, band, order).run();
}

}  // namespace marzipan
