// InverseLattice's per-node work (warp_lattice.hpp): the flow integrated backwards at the
// nodes, and the base's blocks of one value with their counts. Conventions are the header's.
#include "engine/level_set/warp_lattice.hpp"

#include <cmath>

namespace marzipan::level_set::warp {

void InverseLattice::build(const Velocity& v, const Box& work, bool withBlocks, ThreadPool& pool, const ProgressShare& progress) {
  origin = work.lo;
  for (int a = 0; a < 3; ++a) nodes[a] = (work.size()[a] + kLatticeStep - 1) / kLatticeStep + 1;
  offset.assign(std::size_t(nodes.x) * nodes.y * nodes.z, Vec3{});
  image.resize(offset.size());
  if (withBlocks) {
    nodeBlocks.resize(offset.size());
    for (int a = 0; a < 3; ++a) {
      nodeAxisBlocks[std::size_t(a)].resize(std::size_t(nodes[a]));
      for (int i = 0; i < nodes[a]; ++i) nodeAxisBlocks[std::size_t(a)][std::size_t(i)] = axisBlocks(a, double(origin[a] + kLatticeStep * i));
    }
  }
  const int steps = v.substeps();
  pool.parallelFor(std::size_t(nodes.z), [&](std::size_t k) {
    progress.check();
    for (int j = 0; j < nodes.y; ++j)
      for (int i = 0; i < nodes.x; ++i) {
        const Vec3 p = node(i, j, int(k));
        const std::size_t n = index(i, j, int(k));
        const bool moves = v.moves(p);
        if (moves) {
          image[n] = v.flow(p, steps, -1);
          offset[n] = image[n] - p;
        }
        if (withBlocks)
          nodeBlocks[n] = moves ? blocksOf(p + offset[n])
                                : nodeAxisBlocks[0][std::size_t(i)] | nodeAxisBlocks[1][std::size_t(j)] | nodeAxisBlocks[2][k];
      }
    progress.advance(1.0 / nodes.z);
  });
}

void InverseLattice::findBlocks(const Volume& vol, const DenseGrid& base, const Box& within, float band, ThreadPool& pool) {
  // vol's value per block of kUniformBlock^3 voxels (in volume coordinates, within bricks)
  // over base's box, NaN where it varies, lies within kExactNear of 0 or leaves the domain:
  // a brick stored uniform gives its blocks at once, the others are scanned.
  constexpr int B = kUniformBlock, perBrick = Bricks::kSide / B;
  const Box box = within.intersect(base.box);
  const Int3 b0{blockOf(box.lo.x), blockOf(box.lo.y), blockOf(box.lo.z)};
  const Int3 nb{blockOf(box.hi.x - 1) - b0.x + 1, blockOf(box.hi.y - 1) - b0.y + 1, blockOf(box.hi.z - 1) - b0.z + 1};
  blockOrigin = b0, blockCount = nb, bandValue = band;
  blockValue.assign(std::size_t(nb.x) * std::size_t(nb.y) * std::size_t(nb.z), std::numeric_limits<float>::quiet_NaN());
  const Int3 dims = vol.dims();
  pool.parallelFor(std::size_t(nb.z), [&](std::size_t kz) {
    const int bz = b0.z + int(kz);
    if (bz < 0 || (bz + 1) * B > dims.z) return;
    for (int ky = 0; ky < nb.y; ++ky) {
      const int by = b0.y + ky;
      if (by < 0 || (by + 1) * B > dims.y) continue;
      float* out = blockValue.data() + std::size_t(nb.x) * (std::size_t(ky) + std::size_t(nb.y) * kz);
      for (int kx = 0; kx < nb.x; ++kx) {
        const int bx = b0.x + kx;
        if (bx < 0 || (bx + 1) * B > dims.x) continue;
        const Int3 l{(bx % perBrick) * B, (by % perBrick) * B, (bz % perBrick) * B};
        float u = 0;
        const float* data = vol.brickData({bx / perBrick, by / perBrick, bz / perBrick}, &u);
        bool same = true;
        if (data) {
          u = data[Bricks::index(l)];
          for (int z = 0; z < B; ++z)
            for (int y = 0; y < B; ++y) {
              const float* row = data + Bricks::index(l.x, l.y + y, l.z + z);
              for (int x = 0; x < B; ++x) same &= row[x] == u;
            }
        }
        if (same && std::fabs(u) >= kExactNear) out[kx] = u;
      }
    }
  });
  // The counts, one pass over the blocks (a few thousand).
  const std::size_t cx = std::size_t(nb.x) + 1, cxy = cx * (std::size_t(nb.y) + 1);
  bandCounts.assign(cxy * (std::size_t(nb.z) + 1), 0);
  for (int k = 0; k < nb.z; ++k)
    for (int j = 0; j < nb.y; ++j)
      for (int i = 0; i < nb.x; ++i) {
        const float u = blockAt(b0.x + i, b0.y + j, b0.z + k);
        const std::uint64_t own = u == band ? 1 : u == -band ? std::uint64_t(1) << 32 : 0;
        std::uint64_t* c = bandCounts.data() + std::size_t(i + 1) + cx * std::size_t(j + 1) + cxy * std::size_t(k + 1);
        *c = own + c[-1] + c[-std::ptrdiff_t(cx)] + c[-std::ptrdiff_t(cxy)] - c[-std::ptrdiff_t(cx) - 1] -
             c[-std::ptrdiff_t(cxy) - 1] - c[-std::ptrdiff_t(cxy + cx)] + c[-std::ptrdiff_t(cxy + cx) - 1];
      }
  gridBox = base.box;
}

InverseLattice::NodeBlocks InverseLattice::axisBlocks(int a, double q) const {
  static_assert(kUniformBlock == 4);
  const double from = q - 1e-6 - gridBox.lo[a], to = q + 1e-6 - gridBox.lo[a];
  const int shift = gridBox.lo[a] - kUniformBlock * blockOrigin[a];
  const int first = from >= 0 ? (int(from) + shift) >> 2 : -1;
  const int last = to < gridBox.hi[a] - gridBox.lo[a] - 1 ? (int(to) + 1 + shift) >> 2 : blockCount[a];
  NodeBlocks out{};
  out[a] = first >= 0 ? std::int16_t(first) : kOffBlocks;
  out[a + 3] = last < blockCount[a] ? std::int16_t(-last) : kOffBlocks;
  return out;
}

InverseLattice::NodeBlocks InverseLattice::blocksOf(Vec3 q) const { return axisBlocks(0, q.x) | axisBlocks(1, q.y) | axisBlocks(2, q.z); }

}  // namespace marzipan::level_set::warp
