#include "solids.hpp"

#include <cmath>

#include "errors.hpp"
#include "redistance.hpp"
#include "shapes.hpp"

namespace marzipan {

namespace {

// The marzipan pig in units of N, centred at the origin.
double pig(Vec3 p) {
  using namespace sdf;
  const double k = 0.035;  // blend radius of the smooth union
  double d = ellipsoid(p, {0, 0.02, 0}, {0.27, 0.18, 0.18});                     // body
  d = smoothMin(d, sphere(p, {0.27, 0.1, 0}, 0.13), k);                         // head
  d = smoothMin(d, cylinder(p, {0.39, 0.08, 0}, 0.055, 0.04, 0), 0.02);         // snout
  for (double side : {-1.0, 1.0}) {
    d = smoothMin(d, ellipsoid(p, {0.25, 0.23, side * 0.08}, {0.03, 0.06, 0.045}), 0.02);  // ears
    for (double end : {-0.16, 0.15})
      d = smoothMin(d, cylinder(p, {end, -0.2, side * 0.09}, 0.05, 0.11, 1), k);           // legs
    d = smoothMax(d, -sphere(p, {0.36, 0.16, side * 0.055}, 0.018), 0.01);                 // eye dents
  }
  d = smoothMin(d, torus(p, {-0.3, 0.07, 0}, 0.03, 0.012, 2), 0.015);           // curly tail
  return d;
}

}  // namespace

Volume makeFromFunction(Int3 dims, const std::function<double(Vec3)>& f, bool exact, float band, ThreadPool& pool) {
  Volume vol(dims, band);
  const Int3 bd = vol.brickDims();
  // Half diagonal of a brick (from its centre to its corner voxels) plus the allowed overestimate.
  const double skip = band + Bricks::kCentre * std::sqrt(3.0) + 2.0;
  std::vector<std::vector<BrickChange>> rows(std::size_t(bd.y) * bd.z);
  pool.parallelFor(rows.size(), [&](std::size_t r) {
    const int by = int(r % std::size_t(bd.y)), bz = int(r / std::size_t(bd.y));
    for (int bx = 0; bx < bd.x; ++bx) {
      const Int3 o = Bricks::origin({bx, by, bz});
      const double centre = f({o.x + Bricks::kCentre, o.y + Bricks::kCentre, o.z + Bricks::kCentre});
      if (!std::isfinite(centre)) throw EngineError(ErrorKind::InvalidArgument, "solid", "distance is not finite");
      if (std::fabs(centre) > skip) {
        if (centre < 0) rows[r].push_back({{bx, by, bz}, {}, {nullptr, true}});
        continue;
      }
      auto brick = std::make_shared<Brick>();
      for (int z = 0; z < kBrickSide; ++z)
        for (int y = 0; y < kBrickSide; ++y)
          for (int x = 0; x < kBrickSide; ++x) {
            const Int3 p = o + Int3{x, y, z};
            float v = band;  // past the domain's edge: not evaluated
            if (p.x < dims.x && p.y < dims.y && p.z < dims.z)
              v = float(std::clamp(f({double(p.x), double(p.y), double(p.z)}), double(-band), double(band)));
            brick->v[Bricks::index(x, y, z)] = v;
          }
      const BrickRef ref = vol.canonicalBrick({bx, by, bz}, std::move(brick));
      if (ref.data || ref.inside) rows[r].push_back({{bx, by, bz}, {}, ref});
    }
  });
  std::vector<BrickChange> all;
  for (auto& row : rows) all.insert(all.end(), row.begin(), row.end());
  vol.publish(all, true);
  if (!exact) redistanceVolume(vol, pool);
  return vol;
}

Volume makeSphere(Int3 dims, Vec3 center, double radius, float band) {
  if (!isFinite(center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  requirePositive(radius, "radius");
  return makeFromFunction(dims, [&](Vec3 p) { return sdf::sphere(p, center, radius); }, true, band);
}

Volume makeBox(Int3 dims, Vec3 center, Vec3 halfExtents, float band) {
  if (!isFinite(center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  for (int a = 0; a < 3; ++a) requirePositive(halfExtents[a], "halfExtents");
  return makeFromFunction(dims, [&](Vec3 p) { return sdf::box(p, center, halfExtents); }, true, band);
}

Volume makeSolid(SolidKind kind, Int3 dims, float band, ThreadPool& pool) {
  const double n = std::min({dims.x, dims.y, dims.z});
  const Vec3 c{(dims.x - 1) / 2.0, (dims.y - 1) / 2.0, (dims.z - 1) / 2.0};
  switch (kind) {
    case SolidKind::Empty:
      return Volume(dims, band);
    case SolidKind::Sphere:
      return makeFromFunction(dims, [&](Vec3 p) { return sdf::sphere(p, c, 0.35 * n); }, true, band, pool);
    case SolidKind::Box:
      return makeFromFunction(dims, [&](Vec3 p) { return sdf::box(p, c, {0.25 * n, 0.25 * n, 0.25 * n}); }, true, band,
                              pool);
    case SolidKind::Torus:
      return makeFromFunction(dims, [&](Vec3 p) { return sdf::torus(p, c, 0.28 * n, 0.1 * n, 1); }, true, band, pool);
    case SolidKind::Cylinder:
      return makeFromFunction(dims, [&](Vec3 p) { return sdf::cylinder(p, c, 0.2 * n, 0.3 * n, 1); }, true, band,
                              pool);
    case SolidKind::Dumbbell:
      return makeFromFunction(
          dims,
          [&](Vec3 p) {
            const double s = 0.17 * n, off = 0.27 * n;
            double d = std::min(sdf::sphere(p, c + Vec3{off, 0, 0}, s), sdf::sphere(p, c - Vec3{off, 0, 0}, s));
            return std::min(d, sdf::cylinder(p, c, 0.06 * n, off, 0));
          },
          false, band, pool);  // a union of distances is only a bound inside
    case SolidKind::Pig:
      return makeFromFunction(dims, [&](Vec3 p) { return n * pig((p - c) / n); }, false, band, pool);
  }
  throw EngineError(ErrorKind::InvalidArgument, "solid", "unknown solid");
}

}  // namespace marzipan
