// Analytic signed distances of the primitive shapes that solids and constructive tools are
// made of. Sign and units as in volume.hpp. All are exact Euclidean distances except the
// ellipsoid (a bound, exact on its axes) and the smooth blends (exact away from the blend).
#pragma once

#include <algorithm>
#include <cmath>

#include "geometry.hpp"

namespace marzipan::sdf {

inline double sphere(Vec3 p, Vec3 c, double r) { return length(p - c) - r; }

// Axis-aligned box with half extents h.
inline double box(Vec3 p, Vec3 c, Vec3 h) {
  const Vec3 q{std::fabs(p.x - c.x) - h.x, std::fabs(p.y - c.y) - h.y, std::fabs(p.z - c.z) - h.z};
  const Vec3 out{std::max(q.x, 0.0), std::max(q.y, 0.0), std::max(q.z, 0.0)};
  return length(out) + std::min(std::max({q.x, q.y, q.z}), 0.0);
}

// Capped cylinder of radius r and half height h along `axis` (0 = x, 1 = y, 2 = z).
inline double cylinder(Vec3 p, Vec3 c, double r, double h, int axis) {
  const Vec3 d = p - c;
  const double along = d[axis];
  const double radial = std::sqrt(std::max(0.0, dot(d, d) - along * along));
  const double qr = radial - r, qa = std::fabs(along) - h;
  return std::min(std::max(qr, qa), 0.0) + std::hypot(std::max(qr, 0.0), std::max(qa, 0.0));
}

// Torus of major radius R and minor radius r around `axis` through c.
inline double torus(Vec3 p, Vec3 c, double R, double r, int axis) {
  const Vec3 d = p - c;
  const double along = d[axis];
  const double radial = std::sqrt(std::max(0.0, dot(d, d) - along * along));
  return std::hypot(radial - R, along) - r;
}

// Ellipsoid with semi-axes s: a distance bound (|grad| <= 1 near the surface), exact on the axes.
inline double ellipsoid(Vec3 p, Vec3 c, Vec3 s) {
  const Vec3 d = p - c;
  const double k0 = length({d.x / s.x, d.y / s.y, d.z / s.z});
  const double k1 = length({d.x / (s.x * s.x), d.y / (s.y * s.y), d.z / (s.z * s.z)});
  if (k1 == 0) return -std::min({s.x, s.y, s.z});
  return k0 * (k0 - 1.0) / k1;
}

// Polynomial smooth minimum / maximum with blend radius k (k = 0: plain min / max).
inline double smoothMin(double a, double b, double k) {
  if (k <= 0) return std::min(a, b);
  const double h = std::clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0);
  return b + (a - b) * h - k * h * (1.0 - h);
}
inline double smoothMax(double a, double b, double k) { return -smoothMin(-a, -b, k); }

}  // namespace marzipan::sdf
