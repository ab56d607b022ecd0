// Wall thickness by marching the distance field inwards (conventions in thickness.hpp).
#include "thickness.hpp"

#include <algorithm>
#include <cmath>

#include "errors.hpp"
#include "marching_cubes.hpp"

namespace marzipan {

namespace {
constexpr double kMinStep = 0.25;   // vu: never creep, even where d is tiny
constexpr double kTolerance = 1e-3;  // vu: bisection stops at this bracket
constexpr double kSearch = 1.0;      // vu: how far from p the surface is looked for
constexpr double kSearchStep = 0.05;

// The zero of the interpolant along the line next to p: a surface point from a mesh or a
// formula lies within a fraction of a voxel of it, on either side.
double entry(const Volume& vol, Vec3 p, Vec3 in) {
  const bool outside = vol.sample(p) > 0;
  const double dir = outside ? 1 : -1;
  double t = 0;
  for (; std::fabs(t) < kSearch; t += dir * kSearchStep)
    if ((vol.sample(p + in * (t + dir * kSearchStep)) > 0) != outside) break;
  double lo = t, hi = t + dir * kSearchStep;  // sample(lo) on p's side, sample(hi) across
  if (std::fabs(t) >= kSearch) return 0;      // no zero nearby: measure from p itself
  while (std::fabs(hi - lo) > kTolerance) {
    const double mid = 0.5 * (lo + hi);
    ((vol.sample(p + in * mid) > 0) == outside ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

double thicknessAt(const Volume& vol, Vec3 p, Vec3 n) {
  const Vec3 in = n * -1.0;
  const Vec3 dims{double(vol.dims().x), double(vol.dims().y), double(vol.dims().z)};
  // The longest chord the domain (grown by one voxel of +band) can hold.
  const double limit = length(dims) + 4;
  const double start = entry(vol, p, in);
  double t = start + kTolerance, prev = start;
  for (;;) {
    const double d = vol.sample(p + in * t);
    if (d > 0) break;
    prev = t;
    t += std::max(-d, kMinStep);
    if (t - start > limit) return limit;
  }
  // The exit lies in (prev, t]: the interpolant is <= 0 at prev (or the surface itself) and > 0 at t.
  double lo = prev, hi = t;
  while (hi - lo > kTolerance) {
    const double mid = 0.5 * (lo + hi);
    (vol.sample(p + in * mid) > 0 ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi) - start;
}

ThicknessReport analyzeThickness(const Volume& vol, double min, std::size_t maxPlaces, double spacing, ThreadPool& pool) {
  if (!(std::isfinite(min) && min > 0)) throw EngineError(ErrorKind::InvalidArgument, "min_vu", "must be a finite number of vu above 0");
  const Mesh mesh = extractMesh(vol, pool);
  ThicknessReport r;
  r.points = mesh.vertexCount();
  if (r.points == 0) return r;
  std::vector<double> thickness(r.points);
  constexpr std::size_t kChunk = 1024;
  pool.parallelFor((r.points + kChunk - 1) / kChunk, [&](std::size_t c) {
    for (std::size_t v = c * kChunk; v < std::min(r.points, (c + 1) * kChunk); ++v)
      thickness[v] = thicknessAt(vol, mesh.position(v), normalized(mesh.normal(v)));
  });
  r.thinnest = *std::min_element(thickness.begin(), thickness.end());
  std::vector<std::size_t> thin;
  for (std::size_t v = 0; v < r.points; ++v)
    if (thickness[v] < min) thin.push_back(v);
  r.below = thin.size();
  std::stable_sort(thin.begin(), thin.end(), [&](std::size_t a, std::size_t b) { return thickness[a] < thickness[b]; });
  for (const std::size_t v : thin) {
    if (r.places.size() >= maxPlaces) break;
    const Vec3 p = mesh.position(v);
    const bool near = std::any_of(r.places.begin(), r.places.end(),
                                  [&](const ThinPlace& q) { return length(q.point - p) < spacing; });
    if (!near) r.places.push_back({p, normalized(mesh.normal(v)), thickness[v]});
  }
  return r;
}

}  // namespace marzipan
