#include "dense_grid.hpp"

#include "volume.hpp"

namespace marzipan {

DenseGrid DenseGrid::gather(const Volume& vol, const Box& b) {
  DenseGrid g;
  g.box = b;
  g.size = b.size();
  g.sx = std::size_t(g.size.x);
  g.sxy = g.sx * std::size_t(g.size.y);
  g.v.resize(std::size_t(b.voxels()));
  vol.gather(b, g.v.data());
  return g;
}

}  // namespace marzipan
