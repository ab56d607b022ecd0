#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include "engine/solids.hpp"
#include "engine/stencil.hpp"

using namespace marzipan;

namespace {
// A linear field with slopes that floats hold exactly: central differences give them back exactly.
float linear(Int3 p) { return 0.5f * float(p.x) - 0.25f * float(p.y) + 1.0f * float(p.z) - 3.0f; }
}  // namespace

TEST_CASE("the gradient stencil gives the exact slope of a linear field from an array or a reader", "[stencil]") {
  const Int3 n{5, 6, 7};
  std::vector<float> a(std::size_t(n.x * n.y * n.z));
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) a[std::size_t(x + n.x * (y + n.y * z))] = linear({x, y, z});
  const Int3 p{2, 3, 4};
  const GradStencil fromArray =
      GradStencil::inArray(&a[std::size_t(p.x + n.x * (p.y + n.y * p.z))], 1, n.x, n.x * n.y);
  const GradStencil fromReader = GradStencil::around(p, linear);
  for (const GradStencil& s : {fromArray, fromReader}) {
    CHECK(s.gradient() == Vec3{0.5, -0.25, 1.0});
    float g[3];
    s.gradient(g);
    CHECK(g[0] == 0.5f);
    CHECK(g[1] == -0.25f);
    CHECK(g[2] == 1.0f);
    CHECK(s.difference(0) == 1.0f);
    CHECK(s.difference(1) == -0.5f);
    CHECK(s.difference(2) == 2.0f);
    CHECK(s.length() == Approx(std::sqrt(0.25 + 0.0625 + 1.0)).epsilon(1e-15));
  }
}

TEST_CASE("the gradient stencil over a distance field has unit length near a sphere's surface", "[stencil]") {
  const Volume vol = makeSphere({32, 32, 32}, {15.5, 16.0, 16.25}, 9.0);
  const Int3 p{25, 16, 16};  // 0.5 vu outside the sphere, on the x axis through its centre
  const GradStencil s = GradStencil::around(p, [&](Int3 q) { return vol.at(q); });
  CHECK(s.length() == Approx(1.0).margin(0.01));
  CHECK(s.gradient().x == Approx(1.0).margin(0.01));
  CHECK(vol.voxelGradient(p) == s.gradient());
}
