#include "dense_grid.hpp"

#include "volume.hpp"

namespace marzipan {

DenseGrid DenseGrid::gather(const Volume& vol, const Box& b) {
  DenseGrid g;
  g.gatherFrom(vol, b);
  return g;
}

void DenseGrid::gatherFrom(const Volume& vol, const Box& b) {
  box = b;
  size = b.size();
  sx = std::size_t(size.x);
  sxy = sx * std::size_t(size.y);
  v.resize(std::size_t(b.voxels()));
  vol.gather(b, v.data());
}

}  // namespace marzipan
