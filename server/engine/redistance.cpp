#include "redistance.hpp"

#include <cmath>

#include "chunked_pass.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

MarchStats redistanceRegion(DenseGrid& g, const Box& region, float band, Outside outside,
                            const RedistanceOptions& options) {
  const Box r = region.intersect(g.box);
  std::vector<MarchState> state(g.v.size(), outside == Outside::Source ? MarchState::Source : MarchState::Ignored);
  std::vector<std::size_t> kept;
  const float* values = g.v.data();
  MarchState* states = state.data();
  const int exactSide = options.exactSide;
  const std::uint8_t* mask = options.mask ? options.mask->data() : nullptr;
  // On the side that is already exact a voxel stays; elsewhere it is reset unless kept.
  auto resetOrExact = [exactSide](float v) {
    return exactSide != 0 && (v < 0) == (exactSide < 0) ? MarchState::Source : MarchState::Unknown;
  };
  for (int z = r.lo.z; z < r.hi.z; ++z)
    for (int y = r.lo.y; y < r.hi.y; ++y) {
      std::size_t i = g.index({r.lo.x, y, z});
      for (int x = r.lo.x; x < r.hi.x; ++x, ++i) {
        if (mask && !(mask[i] & kRedistanceReset)) continue;  // stays a source
        const float v = values[i];
        // Further than sqrt(3) from the surface: neither on it nor adjacent to it.
        if (std::fabs(v) >= 1.75f) {
          states[i] = resetOrExact(v);
          continue;
        }
        bool adjacent = v == 0;  // on the surface itself (grid-aligned faces, edges, corners)
        const bool neg = v < 0;
        const Int3 p{x, y, z};
        for (int a = 0; a < 3 && !adjacent; ++a) {
          const std::size_t s = g.stride(a);
          if (p[a] > g.box.lo[a] && (values[i - s] < 0) != neg) adjacent = true;
          if (p[a] + 1 < g.box.hi[a] && (values[i + s] < 0) != neg) adjacent = true;
        }
        if (resetOrExact(v) == MarchState::Source) {
          states[i] = MarchState::Source;
        } else if (adjacent) {
          states[i] = MarchState::Source;
          kept.push_back(i);
        } else {
          states[i] = MarchState::Unknown;
        }
      }
    }
  if (options.normalizeKept) {
    if (options.mask)
      std::erase_if(kept, [&](std::size_t i) { return !((*options.mask)[i] & kRedistanceNormalize); });
    std::vector<float> scaled(kept.size());
    for (std::size_t k = 0; k < kept.size(); ++k) {
      const std::size_t i = kept[k];
      const Int3 p = g.point(i);
      double g2 = 0;
      for (int a = 0; a < 3; ++a) {
        const std::size_t s = g.stride(a);
        const double lo = p[a] > g.box.lo[a] ? g.v[i - s] : g.v[i];
        const double hi = p[a] + 1 < g.box.hi[a] ? g.v[i + s] : g.v[i];
        const double span = (p[a] > g.box.lo[a] ? 1 : 0) + (p[a] + 1 < g.box.hi[a] ? 1 : 0);
        const double d = span > 0 ? (hi - lo) / span : 0;
        g2 += d * d;
      }
      // The surface crosses an edge to an opposite-sign neighbour within t = v / (v - v_n) vu,
      // so no distance exceeds the nearest such t; this bounds the result where the gradient
      // is small (a kink between two surfaces), where v / |grad| alone would explode.
      const double v = g.v[i];
      double bound = 1.0;
      for (int a = 0; a < 3; ++a) {
        const std::size_t s = g.stride(a);
        if (p[a] > g.box.lo[a] && (g.v[i - s] < 0) != (v < 0)) bound = std::min(bound, v / (v - g.v[i - s]));
        if (p[a] + 1 < g.box.hi[a] && (g.v[i + s] < 0) != (v < 0)) bound = std::min(bound, v / (v - g.v[i + s]));
      }
      const double len = std::sqrt(g2);
      const double mag = len > 1e-6 ? std::min(std::fabs(v) / len, bound) : bound;
      scaled[k] = float(std::copysign(mag, v));
    }
    for (std::size_t k = 0; k < kept.size(); ++k) g.v[kept[k]] = scaled[k];
  }
  return fastMarch(g, state, band, options.order);
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
