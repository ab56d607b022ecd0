// Helpers shared by the mesh tests (test_mesh_io.cpp, test_mesh_to_volume.cpp).
#pragma once

#include <array>
#include <span>
#include <string>
#include <vector>

#include "engine/errors.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/solids.hpp"

namespace marzipan::test {

using Corner = std::array<float, 3>;
using Triangle = std::array<Corner, 3>;

// The triangles as corner positions, whatever the vertex numbering.
inline std::vector<Triangle> triangles(const Mesh& m) {
  std::vector<Triangle> out;
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    Triangle tri;
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a)
        tri[std::size_t(k)][std::size_t(a)] = m.positions[3 * m.indices[3 * t + std::size_t(k)] + std::size_t(a)];
    out.push_back(tri);
  }
  return out;
}

inline std::span<const std::uint8_t> bytesOf(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// Message of the Format error that f throws ("" when it throws nothing or something else).
template <class F>
std::string formatError(F&& f) {
  try {
    f();
  } catch (const EngineError& e) {
    return e.kind() == ErrorKind::Format ? std::string(e.what()) : std::string();
  }
  return {};
}

inline Mesh tetrahedron() {
  Mesh m;
  m.positions = {2, 2, 2, 12, 2, 2, 2, 12, 2, 2, 2, 12};
  m.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

inline const Vec3 kCentre{35.3, 36.1, 34.7};
inline constexpr double kRadius = 30;

inline const Mesh& sphereMesh() {
  static const Mesh m = extractMesh(makeSphere({72, 72, 72}, kCentre, kRadius));
  return m;
}

}  // namespace marzipan::test
