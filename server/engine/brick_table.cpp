#include "brick_table.hpp"

namespace marzipan {

BrickTable::BrickTable(const Volume& vol)
    : vol_(vol), band_(vol.band()), dims_(vol.dims()), slots_(vol.brickDims(), 1) {
  const Int3 n = vol.brickDims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        Slot& s = slots_[Int3{x, y, z}];
        float u;
        s.data = vol.brickData({x, y, z}, &u);
        s.inside = !s.data && u < 0;
      }
}

float BrickTable::at(Int3 p) const {
  if (p.x < 0 || p.y < 0 || p.z < 0 || p.x >= dims_.x || p.y >= dims_.y || p.z >= dims_.z) return band_;
  float u;
  const float* d = data(Bricks::brickOf(p), &u);
  return d ? d[Bricks::indexOf(p)] : u;
}

}  // namespace marzipan
