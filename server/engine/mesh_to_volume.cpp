// Mesh to volume (conventions in mesh_to_volume.hpp). importMesh runs as named steps: check the
// numbers, weld and check the surface, prepare triangles and pseudonormals, bin triangles into
// the bricks they can reach, compute exact distances in those bricks, then settle the signs of
// every voxel beyond the band.
#include "mesh_to_volume.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <unordered_map>

#include "brick.hpp"
#include "errors.hpp"
#include "mesh_format.hpp"
#include "mesh_reading.hpp"

namespace marzipan {

using namespace mesh_reading;

Mesh fitMeshToDomain(const Mesh& m, Int3 dims, double margin) {
  requireFinite(margin, "margin");
  if (m.vertexCount() == 0) formatError("mesh has no vertices");
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const Vec3 p = m.position(v);
    if (!isFinite(p)) formatError("coordinate is not finite");
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
  }
  double scale = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double room = dims[a] - 1 - 2 * margin;
    if (!(room > 0)) throw EngineError(ErrorKind::InvalidArgument, "margin", "leaves no room in the domain");
    if (hi[a] > lo[a]) scale = std::min(scale, room / (hi[a] - lo[a]));
  }
  if (!std::isfinite(scale)) formatError("mesh has no extent");
  Mesh out = m;
  for (std::size_t v = 0; v < m.vertexCount(); ++v)
    for (int a = 0; a < 3; ++a) {
      const double c = (m.positions[3 * v + std::size_t(a)] - 0.5 * (lo[a] + hi[a])) * scale + 0.5 * (dims[a] - 1);
      out.positions[3 * v + std::size_t(a)] = float(c);
    }
  return out;
}

namespace {

enum Feature : std::uint8_t { kFace, kVertex0, kVertex1, kVertex2, kEdge01, kEdge12, kEdge20 };

struct Triangle {
  Vec3 a, b, c;
  Vec3 centre;
  double radius;
  std::uint32_t v[3];
  Vec3 normal;    // unit face normal
  Vec3 edgeN[3];  // pseudonormals of edges 01, 12, 20
};

// Closest point of t to p (Ericson, Real-Time Collision Detection 5.1.5) and the feature it
// lies on; the feature picks the pseudonormal that decides the sign.
Vec3 closestPoint(const Triangle& t, Vec3 p, Feature& f) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return f = kVertex0, t.a;
  const Vec3 bp = p - t.b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return f = kVertex1, t.b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return f = kEdge01, t.a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - t.c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return f = kVertex2, t.c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return f = kEdge20, t.a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return f = kEdge12, t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  f = kFace;
  return t.a + ab * (vb * denom) + ac * (vc * denom);
}

double distanceSquared(const Triangle& t, Vec3 p) {
  Feature f;
  const Vec3 d = p - closestPoint(t, p, f);
  return dot(d, d);
}

// Solid angle of the triangle seen from p (Van Oosterom and Strackee), positive when p sees
// its back (inside for an outward triangle).
double solidAngle(const Triangle& t, Vec3 p) {
  const Vec3 a = t.a - p, b = t.b - p, c = t.c - p;
  const double la = length(a), lb = length(b), lc = length(c);
  const double num = dot(a, cross(b, c));
  const double den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
  return 2 * std::atan2(num, den);
}

double angleAt(Vec3 p, Vec3 q, Vec3 r) {
  const Vec3 u = normalized(q - p), w = normalized(r - p);
  return std::acos(std::clamp(dot(u, w), -1.0, 1.0));
}

std::uint64_t edgeKey(std::uint32_t a, std::uint32_t b) { return std::uint64_t(std::min(a, b)) << 32 | std::max(a, b); }

// --- the steps of importMesh ---------------------------------------------------------------

Vec3 point(Int3 g) { return {double(g.x), double(g.y), double(g.z)}; }

// What no surface check can repair: counts, indices and non-finite numbers.
void requireImportable(const Mesh& m) {
  if (m.positions.size() % 3 != 0 || m.indices.size() % 3 != 0)
    formatError("positions and indices must come in threes");
  if (m.indices.empty()) formatError("mesh has no triangles");
  checkTriangleCount(m.triangleCount());
  for (const float c : m.positions)
    if (!std::isfinite(c)) formatError("coordinate is not finite");
  for (const std::uint32_t i : m.indices)
    if (i >= m.vertexCount()) formatError("vertex index " + std::to_string(i) + " out of range");
  if (!m.colors.empty() && m.colors.size() != m.positions.size()) formatError("colours must be one per vertex");
}

// The mesh with vertices at identical positions merged and collapsed triangles dropped, checked
// closed, manifold and consistently oriented, and turned outward if it was inside out. Welding
// keeps the colours apart: a colour belongs to a corner of a triangle, as the file gave it (a
// cube with a red top face may share its corners with blue sides), so they come out per kept
// triangle and corner in `cornerColors` when m has colours.
Mesh closedOutwardMesh(const Mesh& m, std::vector<Rgb8>& cornerColors) {
  Welder w;
  std::vector<std::uint32_t> remap(m.vertexCount());
  for (std::size_t v = 0; v < m.vertexCount(); ++v)
    remap[v] = w.add(m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]);
  Mesh mesh;
  mesh.positions = std::move(w.positions);
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const std::uint32_t a = remap[m.indices[3 * t]], b = remap[m.indices[3 * t + 1]], c = remap[m.indices[3 * t + 2]];
    if (a == b || b == c || c == a) continue;
    mesh.indices.insert(mesh.indices.end(), {a, b, c});
    if (!m.colors.empty())
      for (int k = 0; k < 3; ++k) cornerColors.push_back(m.color(m.indices[3 * t + std::size_t(k)]));
  }
  if (mesh.indices.empty()) formatError("mesh has only degenerate triangles");
  const EdgeCheck check = checkEdges(mesh);
  if (check.boundary)
    formatError("mesh is not closed: " + std::to_string(check.boundary) + " edges belong to a single triangle");
  if (check.nonManifold)
    formatError("mesh is not manifold: " + std::to_string(check.nonManifold) +
                " edges belong to more than two triangles");
  if (check.misoriented)
    formatError("mesh is not consistently oriented: " + std::to_string(check.misoriented) +
                " edges run the same way in both their triangles");
  if (meshVolume(mesh) < 0)
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      std::swap(mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]);
      if (!cornerColors.empty()) std::swap(cornerColors[3 * t + 1], cornerColors[3 * t + 2]);
    }
  return mesh;
}

// Triangles with unit normals and bounding spheres, angle-weighted vertex pseudonormals, and
// edge pseudonormals as the sum of the two faces' normals (the mesh is closed, so every edge
// has exactly two).
struct SignedTriangles {
  std::vector<Triangle> tris;
  std::vector<Vec3> vertexN;

  // The pseudonormal of a triangle's feature: whichever side of it p lies on is p's side.
  Vec3 pseudonormal(const Triangle& t, Feature f) const {
    switch (f) {
      case kFace:
        return t.normal;
      case kVertex0:
        return vertexN[t.v[0]];
      case kVertex1:
        return vertexN[t.v[1]];
      case kVertex2:
        return vertexN[t.v[2]];
      case kEdge01:
        return t.edgeN[0];
      case kEdge12:
        return t.edgeN[1];
      case kEdge20:
        return t.edgeN[2];
    }
    return t.normal;
  }
};

SignedTriangles prepareTriangles(const Mesh& mesh) {
  const std::size_t nt = mesh.triangleCount();
  SignedTriangles s;
  s.tris.resize(nt);
  s.vertexN.resize(mesh.vertexCount());
  std::unordered_map<std::uint64_t, Vec3> edgeSum;
  edgeSum.reserve(nt * 3 / 2);
  for (std::size_t t = 0; t < nt; ++t) {
    Triangle& tr = s.tris[t];
    for (int k = 0; k < 3; ++k) tr.v[k] = mesh.indices[3 * t + std::size_t(k)];
    tr.a = mesh.position(tr.v[0]), tr.b = mesh.position(tr.v[1]), tr.c = mesh.position(tr.v[2]);
    tr.normal = normalized(cross(tr.b - tr.a, tr.c - tr.a));
    tr.centre = (tr.a + tr.b + tr.c) / 3.0;
    tr.radius = std::max({length(tr.a - tr.centre), length(tr.b - tr.centre), length(tr.c - tr.centre)});
    const Vec3 p[3] = {tr.a, tr.b, tr.c};
    for (int k = 0; k < 3; ++k) {
      if (tr.normal == Vec3{}) break;
      s.vertexN[tr.v[k]] = s.vertexN[tr.v[k]] + tr.normal * angleAt(p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
      Vec3& e = edgeSum[edgeKey(tr.v[k], tr.v[(k + 1) % 3])];
      e = e + tr.normal;
    }
  }
  for (Triangle& tr : s.tris)
    for (int k = 0; k < 3; ++k) tr.edgeN[k] = edgeSum[edgeKey(tr.v[k], tr.v[(k + 1) % 3])];
  return s;
}

// Per brick, the triangles that can come within the band of one of its voxels (every voxel of a
// brick lies within half a diagonal of its centre), in triangle order: triangles[first[b] ..
// first[b] + count[b]). Zero-area triangles are left out (their points lie on neighbouring
// triangles' edges, and they have no normal).
struct TriangleBins {
  BrickGrid<std::uint32_t> first, count;
  std::vector<std::uint32_t> triangles;
};

[[noreturn]] void tooManyPairs() {
  throw EngineError(ErrorKind::TooLarge, "mesh", "too many triangle and brick pairs within the band");
}

TriangleBins binTriangles(const std::vector<Triangle>& tris, Int3 grid, float band) {
  const double reach = band + Bricks::kCentre * std::sqrt(3.0) + 1e-6;
  TriangleBins bins{BrickGrid<std::uint32_t>(grid, 0), BrickGrid<std::uint32_t>(grid, 0), {}};
  // Calls fn(brick) for every brick a triangle can reach.
  auto forEachReached = [&](const Triangle& tr, auto&& fn) {
    Int3 lo, hi;
    for (int a = 0; a < 3; ++a) {
      const double mn = std::min({tr.a[a], tr.b[a], tr.c[a]}) - band, mx = std::max({tr.a[a], tr.b[a], tr.c[a]}) + band;
      lo[a] = int(std::clamp(std::floor(mn / kBrickSide), 0.0, double(grid[a])));
      hi[a] = int(std::clamp(std::floor(mx / kBrickSide), -1.0, double(grid[a] - 1)));
    }
    for (int z = lo.z; z <= hi.z; ++z)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x) {
          const Vec3 centre = point(Bricks::origin({x, y, z})) + Vec3{Bricks::kCentre, Bricks::kCentre, Bricks::kCentre};
          if (distanceSquared(tr, centre) <= reach * reach) fn(Int3{x, y, z});
        }
  };
  for (const Triangle& tr : tris) {
    if (tr.normal == Vec3{}) continue;
    forEachReached(tr, [&](Int3 b) {
      if (bins.count[b] == std::numeric_limits<std::uint32_t>::max()) tooManyPairs();
      ++bins.count[b];
    });
  }
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < bins.count.size(); ++i) {
    bins.first[i] = std::uint32_t(total);
    total += bins.count[i];
    if (total > std::numeric_limits<std::uint32_t>::max()) tooManyPairs();
  }
  bins.triangles.resize(std::size_t(total));
  BrickGrid<std::uint32_t> next = bins.first;
  for (std::size_t t = 0; t < tris.size(); ++t) {
    if (tris[t].normal == Vec3{}) continue;
    forEachReached(tris[t], [&](Int3 b) { bins.triangles[next[b]++] = std::uint32_t(t); });
  }
  return bins;
}

// The signed distance from p to the nearest of the candidate triangles, or NaN when none lies
// within the band; then *nearest is that triangle's index and *foot its closest point to p.
float signedDistance(const SignedTriangles& st, const std::uint32_t* candidates, std::size_t n, Vec3 p, float band,
                     std::uint32_t* nearest, Vec3* foot) {
  double best = double(band) * band;
  const Triangle* bestTri = nullptr;
  Feature bestFeature = kFace;
  Vec3 bestPoint;
  for (std::size_t k = 0; k < n; ++k) {
    const Triangle& tr = st.tris[candidates[k]];
    const Vec3 dc = p - tr.centre;
    const double cull = std::sqrt(best) + tr.radius;
    if (dot(dc, dc) > cull * cull) continue;
    Feature f;
    const Vec3 q = closestPoint(tr, p, f);
    const double d2 = dot(p - q, p - q);
    if (d2 < best) best = d2, bestTri = &tr, bestFeature = f, bestPoint = q, *nearest = candidates[k];
  }
  if (!bestTri) return std::numeric_limits<float>::quiet_NaN();
  *foot = bestPoint;
  const float d = float(std::sqrt(best));
  return dot(p - bestPoint, st.pseudonormal(*bestTri, bestFeature)) < 0 ? -d : d;
}

// The colour at q, a point of triangle t, from its corners' colours by barycentric weights
// (of the sRGB bytes), each channel rounded.
Rgb8 colorOnTriangle(const Triangle& t, const Rgb8* corners, Vec3 q) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, aq = q - t.a;
  const double d00 = dot(ab, ab), d01 = dot(ab, ac), d11 = dot(ac, ac), d20 = dot(aq, ab), d21 = dot(aq, ac);
  const double den = d00 * d11 - d01 * d01;
  // Binned triangles have a normal, so den > 0; the clamp only absorbs rounding at the edges.
  const double v = std::clamp((d11 * d20 - d01 * d21) / den, 0.0, 1.0);
  const double w = std::clamp((d00 * d21 - d01 * d20) / den, 0.0, 1.0 - v);
  const double u = 1 - v - w;
  auto mix = [&](std::uint8_t Rgb8::*c) {
    return std::uint8_t(std::clamp(std::lround(u * corners[0].*c + v * corners[1].*c + w * corners[2].*c), 0l, 255l));
  };
  return {mix(&Rgb8::r), mix(&Rgb8::g), mix(&Rgb8::b)};
}

// The bricks that have candidate triangles, in z, y, x order, with exact distances in their
// band voxels and NaN in the others; voxels past the domain's edge hold +band. With corner
// colours, each brick's channels too: a band voxel takes the colour of its nearest surface
// point, every other voxel the base colour.
struct NearBricks {
  std::vector<Int3> bricks;
  BrickGrid<std::int32_t> slot;  // index in bricks, -1 for a brick without candidates
  std::vector<std::shared_ptr<Brick>> data;
  std::vector<std::shared_ptr<BrickPaint>> paint;  // empty without colours
};

NearBricks exactDistances(const SignedTriangles& st, const std::vector<Rgb8>& cornerColors, const TriangleBins& bins,
                          Int3 dims, float band, Rgb8 base, ThreadPool& pool) {
  const Int3 grid = bins.count.grid();
  NearBricks near{{}, BrickGrid<std::int32_t>(grid, 0, -1), {}, {}};
  for (int z = 0; z < grid.z; ++z)
    for (int y = 0; y < grid.y; ++y)
      for (int x = 0; x < grid.x; ++x)
        if (bins.count[Int3{x, y, z}] > 0) {
          near.slot[Int3{x, y, z}] = std::int32_t(near.bricks.size());
          near.bricks.push_back({x, y, z});
        }
  near.data.resize(near.bricks.size());
  const bool colored = !cornerColors.empty();
  if (colored) near.paint.resize(near.bricks.size());
  pool.parallelFor(near.bricks.size(), [&](std::size_t i) {
    auto br = std::make_shared<Brick>();
    std::shared_ptr<BrickPaint> bp = colored ? std::make_shared<BrickPaint>() : nullptr;
    const Int3 b = near.bricks[i];
    const std::uint32_t* candidates = bins.triangles.data() + bins.first[b];
    for (int k = 0; k < kBrickVoxels; ++k) {
      const Int3 g = Bricks::origin(b) + Bricks::local(k);
      if (g.x >= dims.x || g.y >= dims.y || g.z >= dims.z) {
        br->v[k] = band;
        if (bp) bp->t[k] = texelOf(base);
        continue;
      }
      std::uint32_t nearest = 0;
      Vec3 foot;
      br->v[k] = signedDistance(st, candidates, bins.count[b], point(g), band, &nearest, &foot);
      if (bp)
        bp->t[k] = texelOf(std::isnan(br->v[k]) ? base : colorOnTriangle(st.tris[nearest], &cornerColors[3 * nearest], foot));
    }
    near.data[i] = std::move(br);
    if (bp) near.paint[i] = std::move(bp);
  });
  return near;
}

// Signs beyond the band, in z, y, x order: a voxel further than band (>= 2 vu) from the surface
// has the sign of any neighbour, and its x-, y- or z-neighbour before it is settled. Fills the
// NaN voxels of the near bricks and returns every brick of the solid as a change from air.
std::vector<BrickChange> settleFarVoxels(NearBricks& near, const std::vector<Triangle>& tris, const Volume& vol) {
  const Int3 grid = near.slot.grid();
  const float band = vol.band();
  BrickGrid<std::uint8_t> farInside(grid, 0, 0);
  std::optional<bool> seed;
  auto windingInside = [&](Vec3 p) {
    double sum = 0;
    for (const Triangle& tr : tris) sum += solidAngle(tr, p);
    return sum > 2 * std::numbers::pi;
  };
  auto insideAt = [&](Int3 g) {
    const Int3 b = Bricks::brickOf(g);
    const std::int32_t ni = near.slot[b];
    if (ni < 0) return farInside[b] != 0;
    return near.data[std::size_t(ni)]->v[Bricks::indexOf(g)] < 0;
  };
  auto settle = [&](Int3 g) {
    if (g.x > 0) return insideAt(g - Int3{1, 0, 0});
    if (g.y > 0) return insideAt(g - Int3{0, 1, 0});
    if (g.z > 0) return insideAt(g - Int3{0, 0, 1});
    if (!seed) seed = windingInside(point(g));
    return *seed;
  };
  std::vector<BrickChange> changes;
  for (int z = 0; z < grid.z; ++z)
    for (int y = 0; y < grid.y; ++y)
      for (int x = 0; x < grid.x; ++x) {
        const Int3 b{x, y, z};
        const std::int32_t ni = near.slot[b];
        const Int3 o = Bricks::origin(b);
        if (ni < 0) {
          const bool in = settle(o);
          farInside[b] = in;
          if (in) changes.push_back({b, {}, {nullptr, true}});
          continue;
        }
        Brick& br = *near.data[std::size_t(ni)];
        for (int k = 0; k < kBrickVoxels; ++k) {
          float& v = br.v[k];
          if (std::isnan(v)) v = settle(o + Bricks::local(k)) ? -band : band;
        }
        BrickRef ref = vol.canonicalBrick(b, near.data[std::size_t(ni)]);
        if (ref.data && !near.paint.empty()) ref.paint = vol.canonicalPaint(std::move(near.paint[std::size_t(ni)]));
        if (ref.data || ref.inside) changes.push_back({b, {}, ref});
      }
  return changes;
}

}  // namespace

Volume importMesh(const Mesh& m, Int3 dims, float band, ThreadPool& pool) {
  Volume vol(dims, band);  // validates dims and band first
  requireImportable(m);
  std::vector<Rgb8> cornerColors;
  const Mesh mesh = closedOutwardMesh(m, cornerColors);
  const SignedTriangles st = prepareTriangles(mesh);
  const TriangleBins bins = binTriangles(st.tris, vol.brickDims(), band);
  NearBricks near = exactDistances(st, cornerColors, bins, dims, band, vol.baseColor(), pool);
  vol.publish(settleFarVoxels(near, st.tris, vol), true);
  return vol;
}

}  // namespace marzipan
