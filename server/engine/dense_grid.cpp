#include "dense_grid.hpp"

#include <algorithm>

#include "brick.hpp"
#include "progress.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

DenseGrid DenseGrid::gather(const Volume& vol, const Box& b) {
  DenseGrid g;
  g.gatherFrom(vol, b);
  return g;
}

void DenseGrid::gatherFrom(const Volume& vol, const Box& b) { gatherFrom(vol, b, ProgressShare{}); }

void DenseGrid::gatherFrom(const Volume& vol, const Box& b, const ProgressShare& progress) {
  gatherFrom(vol, b, progress, ThreadPool::serial());
}

void DenseGrid::gatherFrom(const Volume& vol, const Box& b, const ProgressShare& progress, ThreadPool& pool) {
  box = b;
  size = b.size();
  sx = std::size_t(size.x);
  sxy = sx * std::size_t(size.y);
  v.resize(std::size_t(b.voxels()));
  if (b.empty()) return;
  const bool parallel = pool.threads() > 1 && b.voxels() >= kParallelGatherVoxels;
  if (!progress.progress && !parallel) {
    vol.gather(b, v.data());
    return;
  }
  // Slabs of the voxels of one brick layer along z (the first and last cut by the box): each is
  // a contiguous part of the grid and reads each of its bricks once.
  const int firstLayer = Bricks::brickOf(b.lo.z);
  const std::size_t slabs = std::size_t(Bricks::brickOf(b.hi.z - 1) - firstLayer + 1);
  (parallel ? pool : ThreadPool::serial()).parallelFor(slabs, [&](std::size_t k) {
    progress.check();
    const int z0 = std::max(b.lo.z, (firstLayer + int(k)) * kBrickSide);
    const int z1 = std::min(b.hi.z, (firstLayer + int(k) + 1) * kBrickSide);
    vol.gather({{b.lo.x, b.lo.y, z0}, {b.hi.x, b.hi.y, z1}}, v.data() + sxy * std::size_t(z0 - b.lo.z));
    progress.advance(double(z1 - z0) / double(size.z));
  });
}

}  // namespace marzipan
