// Small value types shared by the engine and the protocol; standard library only.
// Conventions: coordinates in voxel units (vu); voxel (i,j,k) sits at the point (i,j,k);
// boxes are half-open integer ranges [lo, hi) of voxel indices.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace marzipan {

struct Vec3 {
  double x = 0, y = 0, z = 0;

  double& operator[](int a) { return a == 0 ? x : (a == 1 ? y : z); }
  double operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  friend Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
  friend Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
  friend Vec3 operator*(double s, Vec3 a) { return a * s; }
  friend Vec3 operator/(Vec3 a, double s) { return {a.x / s, a.y / s, a.z / s}; }
  friend bool operator==(Vec3 a, Vec3 b) = default;
};

inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalized(Vec3 a) {
  const double l = length(a);
  return l > 0 ? a / l : Vec3{0, 0, 0};
}
inline bool isFinite(Vec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }

struct Int3 {
  int x = 0, y = 0, z = 0;

  int& operator[](int a) { return a == 0 ? x : (a == 1 ? y : z); }
  int operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  friend Int3 operator+(Int3 a, Int3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend Int3 operator-(Int3 a, Int3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend bool operator==(Int3 a, Int3 b) = default;
};

// Half-open voxel box [lo, hi).
struct Box {
  Int3 lo, hi;

  bool empty() const { return hi.x <= lo.x || hi.y <= lo.y || hi.z <= lo.z; }
  Int3 size() const { return {std::max(0, hi.x - lo.x), std::max(0, hi.y - lo.y), std::max(0, hi.z - lo.z)}; }
  std::int64_t voxels() const {
    const Int3 s = size();
    return std::int64_t(s.x) * s.y * s.z;
  }
  bool contains(Int3 p) const {
    return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x < hi.x && p.y < hi.y && p.z < hi.z;
  }
  Box grown(int m) const { return {{lo.x - m, lo.y - m, lo.z - m}, {hi.x + m, hi.y + m, hi.z + m}}; }
  Box intersect(const Box& o) const {
    return {{std::max(lo.x, o.lo.x), std::max(lo.y, o.lo.y), std::max(lo.z, o.lo.z)},
            {std::min(hi.x, o.hi.x), std::min(hi.y, o.hi.y), std::min(hi.z, o.hi.z)}};
  }
  friend bool operator==(const Box& a, const Box& b) = default;
};

// The smallest voxel box holding every voxel within `radius` of `c` (per axis). Coordinates
// are clamped to +-1e9 before they become ints, so a box far outside every domain stays far
// outside instead of overflowing.
inline Box boxAround(Vec3 c, Vec3 radius) {
  constexpr double kFar = 1e9;
  Box b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = int(std::floor(std::clamp(c[a] - radius[a], -kFar, kFar)));
    b.hi[a] = int(std::ceil(std::clamp(c[a] + radius[a], -kFar, kFar))) + 1;
  }
  return b;
}

}  // namespace marzipan
