#include "dense_grid.hpp"

#include <algorithm>

#include "progress.hpp"
#include "volume.hpp"

namespace marzipan {

DenseGrid DenseGrid::gather(const Volume& vol, const Box& b) {
  DenseGrid g;
  g.gatherFrom(vol, b);
  return g;
}

void DenseGrid::gatherFrom(const Volume& vol, const Box& b) { gatherFrom(vol, b, ProgressShare{}); }

void DenseGrid::gatherFrom(const Volume& vol, const Box& b, const ProgressShare& progress) {
  box = b;
  size = b.size();
  sx = std::size_t(size.x);
  sxy = sx * std::size_t(size.y);
  v.resize(std::size_t(b.voxels()));
  if (!progress.progress) {
    vol.gather(b, v.data());
    return;
  }
  // A slab of whole z-slices is a contiguous part of the grid.
  constexpr int kSlab = 8;
  for (int z = b.lo.z; z < b.hi.z; z += kSlab) {
    progress.check();
    const int end = std::min(z + kSlab, b.hi.z);
    vol.gather({{b.lo.x, b.lo.y, z}, {b.hi.x, b.hi.y, end}}, v.data() + sxy * std::size_t(z - b.lo.z));
    progress.advance(double(end - z) / double(size.z));
  }
}

}  // namespace marzipan
