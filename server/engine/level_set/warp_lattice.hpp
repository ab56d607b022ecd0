// The warps' inverse map on a lattice (InverseLattice): X = the backward flow of the field,
// integrated at nodes kLatticeStep vu apart and interpolated between them at the voxels, and
// the base's blocks of one value that let a lattice cell be resampled by one comparison. The
// per-voxel reads (row(), imageAt(), inverse(), cellValue()) are here, inline in the
// resample's loop; the per-node work (build(), findBlocks()) is warp_lattice.cpp's. Points are
// volume coordinates; the lattice's nodes and a grid's voxels are x fastest.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "engine/dense_grid.hpp"
#include "engine/progress.hpp"
#include "engine/thread_pool.hpp"
#include "engine/level_set/warp_fields.hpp"

namespace marzipan::level_set::warp {

// The inverse map is integrated at the nodes of a lattice kLatticeStep vu apart and
// interpolated trilinearly between them: the flow was 90% of a grab's time when integrated at
// every voxel (and six more times at the voxels next to the zero set). X is smooth at the scale
// of the radius, and only decides the far voxels, whose values the redistance replaces anyway.
constexpr int kLatticeStep = 2;
// Voxels that read less than this through the lattice are read again through the flow
// integrated at the voxel: they hold the zero set (and the lattice's error, measured up to
// 0.76 vu at the peak of a 3-radius grab, stays below the margin).
constexpr float kExactNear = 2.0f;
static_assert(kLatticeStep == 2, "InverseLattice::inverse: a voxel's weights are 0 or 1/2");
// The side of the blocks InverseLattice::findBlocks looks at the base in: a brick holds whole
// ones.
constexpr int kUniformBlock = std::min(4, Bricks::kSide);
static_assert(Bricks::kSide % kUniformBlock == 0);
// The blocks findBlocks looks at cover the support's box grown by this: the lattice's cells
// read within it (their corners' preimages lie in the support or are nodes at most a voxel past
// it, and trilinear() reads the next voxel up); a cell that would read past it is read voxel
// by voxel (cellValue() says NaN).
constexpr int kBlockReach = 2;


struct InverseLattice {
  Int3 origin, nodes;
  std::vector<Vec3> offset;  // X(node) - node, x fastest
  // X(node) as flow() gave it, for the nodes the flow moves (moves()): a voxel on a node that
  // wants the exact flow (the resample, kExactNear) takes it from here, the same bits.
  std::vector<Vec3> image;

  // withBlocks: findBlocks() was called, and each node's blocks are noted (nodeBlocks).
  void build(const Velocity& v, const Box& work, bool withBlocks, ThreadPool& pool, const ProgressShare& progress);

  Vec3 node(int i, int j, int k) const {
    return {double(origin.x + kLatticeStep * i), double(origin.y + kLatticeStep * j), double(origin.z + kLatticeStep * k)};
  }
  std::size_t index(int i, int j, int k) const {
    return std::size_t(i) + std::size_t(nodes.x) * (std::size_t(j) + std::size_t(nodes.y) * std::size_t(k));
  }

  // Where the lattice's cells read one value. A cell's voxels read the base inside the box of
  // its corners' preimages (inverse() interpolates between them); where the base is one value
  // there, at least kExactNear from 0, each of those reads is that value bit for bit and the
  // exact flow is not wanted: deep inside and far outside the solid (most of a grab's support)
  // the resample is then a comparison. findBlocks() notes the base's blocks of one value,
  // cellValue() looks up a cell's.
  std::vector<float> blockValue;
  Int3 blockOrigin, blockCount;
  // Per node, the blocks (from blockOrigin) that trilinear() reads for points within rounding
  // of its preimage: the first's three coordinates and the last's negated, kOffBlocks where
  // that is off the grid or the blocks noted; a cell's blocks are then the lanewise least of
  // its eight corners' (the box of the preimages' blocks is the blocks of the preimages' box:
  // the block of a coordinate is monotonic in it), 8 loads and 7 minima. Per cell, the
  // preimages' box had taken ~450 instructions with the loop over its blocks (a grab at 20 vu
  // looks up ~8,000 cells).
  using NodeBlocks = std::int16_t __attribute__((vector_size(16)));
  static constexpr std::int16_t kOffBlocks = std::numeric_limits<std::int16_t>::min();
  // A grid's blocks along an axis (the support within the domain, grown by a few voxels) fit
  // the lanes.
  static_assert(kMaxDomainSide / kUniformBlock + 16 < std::numeric_limits<std::int16_t>::max());
  std::vector<NodeBlocks> nodeBlocks;
  // The blocks of value +band and of value -band in [0, i) x [0, j) x [0, k) of the blocks
  // noted, packed as plus + 2^32 minus (mod 2^64 the box sums of the inclusion-exclusion are
  // exact): whether a cell's blocks are all one such value is 8 loads.
  std::vector<std::uint64_t> bandCounts;
  float bandValue = 0;
  Box gridBox;

  void findBlocks(const Volume& vol, const DenseGrid& base, const Box& within, float band, ThreadPool& pool);

  // The blocks of the voxels trilinear() reads for points within 1e-6 of the preimage q, all
  // within the grid (off it trilinear() reads +band), as NodeBlocks: a cell's voxels' reads are
  // convex combinations of its corners' preimages up to a few ulps. One vector per axis, which
  // sets its two lanes. From the grid's corner up truncation is the floor (and std::floor a
  // sequence of instructions without SSE4.1), and an arithmetic shift the floor of a division
  // by the block's side: blockOf(c) - blockOrigin for c = int(from) + gridBox.lo.
  NodeBlocks axisBlocks(int a, double q) const;
  NodeBlocks blocksOf(Vec3 q) const;
  // axisBlocks() of the nodes' own coordinates (the preimages of the nodes the flow leaves
  // alone, most of them), per axis.
  std::array<std::vector<NodeBlocks>, 3> nodeAxisBlocks;

  // The value every voxel of cell (i, j, k) reads from the base, when findBlocks() found one
  // block value over all it can read, else NaN.
  float cellValue(int i, int j, int k) const {
    const std::size_t sx = std::size_t(nodes.x), sxy = sx * std::size_t(nodes.y);
    const NodeBlocks* o = nodeBlocks.data() + index(i, j, k);
    const auto least = [](NodeBlocks a, NodeBlocks b) { return a < b ? a : b; };
    const NodeBlocks m = least(least(least(o[0], o[1]), least(o[sx], o[sx + 1])),
                               least(least(o[sxy], o[sxy + 1]), least(o[sxy + sx], o[sxy + sx + 1])));
    if (m[0] < 0 || m[1] < 0 || m[2] < 0 || m[3] == kOffBlocks || m[4] == kOffBlocks || m[5] == kOffBlocks)
      return std::numeric_limits<float>::quiet_NaN();
    const int x0 = m[0], y0 = m[1], z0 = m[2], x1 = -m[3], y1 = -m[4], z1 = -m[5];
    const float value = blockValue[std::size_t(x0) + std::size_t(blockCount.x) * (std::size_t(y0) + std::size_t(blockCount.y) * std::size_t(z0))];
    if (value == bandValue || value == -bandValue) {
      const std::size_t cx = std::size_t(blockCount.x) + 1, cxy = cx * (std::size_t(blockCount.y) + 1);
      const auto at = [&](int x, int y, int z) { return bandCounts[std::size_t(x) + cx * std::size_t(y) + cxy * std::size_t(z)]; };
      const std::uint64_t inBox = at(x1 + 1, y1 + 1, z1 + 1) - at(x0, y1 + 1, z1 + 1) - at(x1 + 1, y0, z1 + 1) - at(x1 + 1, y1 + 1, z0) +
                                  at(x0, y0, z1 + 1) + at(x0, y1 + 1, z0) + at(x1 + 1, y0, z0) - at(x0, y0, z0);
      const std::uint64_t all = std::uint64_t(x1 - x0 + 1) * std::uint64_t(y1 - y0 + 1) * std::uint64_t(z1 - z0 + 1);
      return inBox == (value == bandValue ? all : all << 32) ? value : std::numeric_limits<float>::quiet_NaN();
    }
    if (!(value == value)) return value;
    for (int bz = z0; bz <= z1; ++bz)
      for (int by = y0; by <= y1; ++by)
        for (int bx = x0; bx <= x1; ++bx)
          if (!(blockAt(blockOrigin.x + bx, blockOrigin.y + by, blockOrigin.z + bz) == value)) return std::numeric_limits<float>::quiet_NaN();
    return value;
  }

  // The block of a voxel coordinate (rounding down, also below 0: the grid reaches past the
  // domain by a few voxels).
  static int blockOf(int c) {
    constexpr int kBias = 1 << 12;
    static_assert(kBias % kUniformBlock == 0);
    return (c + kBias) / kUniformBlock - kBias / kUniformBlock;
  }

  float blockAt(int bx, int by, int bz) const {
    return blockValue[std::size_t(bx - blockOrigin.x) +
                      std::size_t(blockCount.x) * (std::size_t(by - blockOrigin.y) + std::size_t(blockCount.y) * std::size_t(bz - blockOrigin.z))];
  }

  // X(p) at the voxel p = (x, y, z) of `work`, the offsets interpolated trilinearly between
  // the nodes of its cell, along row(y, z). The nodes are kLatticeStep = 2 apart, so a voxel's
  // weight along each axis is 0 (on a node's plane) or 1/2: a weight of 0 takes the first of
  // each pair, as a + (b - a) 0 does up to the sign of a zero (which p + offset does not
  // see), and the interpolation runs only across the axes of weight 1/2, half its 4 + 2 + 1
  // steps on average.
  struct Row {
    const Vec3* o;  // the offsets of row (y, z)'s first cell
    bool ty, tz;    // whether its weights along y and z are 1/2
  };
  Row row(int y, int z) const {
    const unsigned dy = unsigned(y - origin.y), dz = unsigned(z - origin.z);
    return {offset.data() + index(0, int(dy / kLatticeStep), int(dz / kLatticeStep)), dy % kLatticeStep != 0, dz % kLatticeStep != 0};
  }
  // X(p) exactly (image) when the voxel p = (x, y, z) of row(y, z) lies on a node, else null.
  // Only for a voxel the flow moves: image holds only the moving nodes' (the others keep a
  // previous call's), and the resample asks only within each row's run of moving voxels.
  const Vec3* imageAt(const Row& r, int x) const {
    const unsigned dx = unsigned(x - origin.x);
    if (r.ty || r.tz || dx % kLatticeStep != 0) return nullptr;
    return image.data() + (r.o - offset.data()) + dx / kLatticeStep;
  }
  Vec3 inverse(const Row& r, Vec3 p, int x) const {
    const unsigned dx = unsigned(x - origin.x);
    const std::size_t sx = std::size_t(nodes.x), sxy = sx * std::size_t(nodes.y);
    const Vec3* o = r.o + dx / kLatticeStep;
    const bool tx = dx % kLatticeStep != 0;
    const auto half = [](Vec3 a, Vec3 b) { return a + (b - a) * 0.5; };
    const auto alongX = [&](std::size_t at) { return tx ? half(o[at], o[at + 1]) : o[at]; };
    Vec3 c = alongX(0);
    if (r.ty) c = half(c, alongX(sx));
    if (r.tz) {
      Vec3 above = alongX(sxy);
      if (r.ty) above = half(above, alongX(sxy + sx));
      c = half(c, above);
    }
    return p + c;
  }
};

}  // namespace marzipan::level_set::warp
