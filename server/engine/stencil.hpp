// The central-difference gradient at one voxel, in the spirit of OpenVDB's GradStencil: the six
// face neighbours are read once, from an array or from any reader, and the stencil answers the
// gradient and its length. Kernels keep their loops and buffers; the finite difference is here.
//
// Conventions: unit vu, so the gradient of a distance field has length 1; the differences are
// taken in float (the field's type) and only then widened, so every caller gets the same bits
// whether it asks for float or double.
#pragma once

#include <cmath>
#include <cstddef>

#include "geometry.hpp"

namespace marzipan {

class GradStencil {
 public:
  // From an array: `centre` points at the voxel, stride[a] is the step to the next voxel along
  // axis a (all six neighbours must be readable).
  static GradStencil inArray(const float* centre, std::ptrdiff_t sx, std::ptrdiff_t sy, std::ptrdiff_t sz) {
    GradStencil s;
    s.diff_[0] = centre[sx] - centre[-sx];
    s.diff_[1] = centre[sy] - centre[-sy];
    s.diff_[2] = centre[sz] - centre[-sz];
    return s;
  }
  // From a reader: read(Int3) gives the value at a voxel (e.g. Volume::at).
  template <class Read>
  static GradStencil around(Int3 p, Read&& read) {
    GradStencil s;
    s.diff_[0] = read(Int3{p.x + 1, p.y, p.z}) - read(Int3{p.x - 1, p.y, p.z});
    s.diff_[1] = read(Int3{p.x, p.y + 1, p.z}) - read(Int3{p.x, p.y - 1, p.z});
    s.diff_[2] = read(Int3{p.x, p.y, p.z + 1}) - read(Int3{p.x, p.y, p.z - 1});
    return s;
  }

  // d(p + e_a) - d(p - e_a): twice the gradient, for callers that only need its direction.
  float difference(int a) const { return diff_[a]; }
  // The gradient, 0.5 * difference, in float or in double.
  void gradient(float g[3]) const {
    for (int a = 0; a < 3; ++a) g[a] = 0.5f * diff_[a];
  }
  Vec3 gradient() const { return {0.5 * diff_[0], 0.5 * diff_[1], 0.5 * diff_[2]}; }
  // |gradient()|, in double.
  double length() const {
    const Vec3 g = gradient();
    return std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
  }

 private:
  float diff_[3] = {0, 0, 0};
};

}  // namespace marzipan
