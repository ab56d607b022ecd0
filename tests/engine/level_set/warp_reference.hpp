// The exact answer a warp of a sphere should give (test_warp.cpp): the signed distance to the
// sphere carried by the warps' own maps (WarpMap, level_set.hpp), and how far a result is from
// it. Sign and units as in volume.hpp (vu, d < 0 inside); voxel p sits at (p.x, p.y, p.z).
//
// The carried surface is a triangulation of the sphere whose vertices are mapped forward,
// refined map by map until every mapped edge is at most kLongestEdge long and its mapped
// midpoint lies within kSagitta of the edge's chord, then cut once more at those midpoints:
// the triangles lie within about kSagitta / 4 of the carried surface, where the warp's tip
// bends within a voxel as much as on its flat sides (refined to half these tolerances
// instead, the snake hook test's means moved by under 1%).
// A voxel's distance is its exact distance to those triangles, and its sign that of its
// preimage (the maps' inverses in reverse order) in the sphere, which does not depend on the
// triangulation.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <unordered_map>
#include <utility>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/volume.hpp"

namespace marzipan::test_warp {

inline constexpr double kLongestEdge = 1.0;
inline constexpr double kSagitta = 0.005;

// The sphere (centre, radius) carried by `maps`, applied first to last.
struct CarriedSphere {
  Vec3 centre;
  double radius = 1;
  std::vector<WarpMap> maps;

  Vec3 forward(Vec3 p) const {
    for (const WarpMap& m : maps) p = m.forward(p);
    return p;
  }
  bool inside(Vec3 p) const {
    for (auto m = maps.rbegin(); m != maps.rend(); ++m) p = m->inverse(p);
    return length(p - centre) < radius;
  }
};

// The closest point to p on the triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
inline Vec3 closestOnTriangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// The carried sphere's triangles (mapped corners), built map by map: the triangulation of the
// sphere is refined, then carried by each map in turn and refined again where that map moved
// it. A triangle is refined while one of its edges fails: longer than kLongestEdge, or its
// midpoint (the image of its midpoint on the sphere) farther than kSagitta from its chord; it
// is then bisected across its longest edge (Rivara's longest-edge bisection, in the carried
// surface's lengths). One map stretches a triangle little, so its triangles stay well shaped
// on the carried surface however far the maps draw it out: a tentacle drawn out of a small cap
// of the sphere is cut into rows along its length, no finer around than its curvature needs
// (splitting each face into four after all the maps cut it as finely around as along: 258,000
// triangles after 10 of a 200 vu snake hook's 97 moves). A triangle whose neighbour split
// their common edge and itself did not leaves a crack no wider than kSagitta, as that edge
// passes.
inline constexpr std::size_t kMostTriangles = 3'000'000;
inline std::vector<std::array<Vec3, 3>> carriedTriangles(const CarriedSphere& s) {
  // An icosahedron's faces, as unit directions, refined below.
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vec3> dir{{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                        {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  const int ico[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                          {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                          {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  std::vector<Vec3> at;  // each vertex carried by the first `applied` maps
  std::size_t applied = 0;
  for (Vec3& u : dir) u = normalized(u), at.push_back(s.centre + u * s.radius);
  constexpr std::uint32_t kNone = ~std::uint32_t(0);
  // Each edge's midpoint on the sphere, carried (a vertex, made when the edge is first tested).
  std::unordered_map<std::uint64_t, std::uint32_t> mids;
  const auto mid = [&](std::uint32_t i, std::uint32_t j) {
    const std::uint64_t key = std::uint64_t(std::min(i, j)) << 32 | std::max(i, j);
    const auto found = mids.find(key);
    if (found != mids.end()) return found->second;
    const Vec3 u = normalized(dir[i] + dir[j]);
    Vec3 p = s.centre + u * s.radius;
    for (std::size_t k = 0; k < applied; ++k) p = s.maps[k].forward(p);
    dir.push_back(u), at.push_back(p);
    mids.emplace(key, std::uint32_t(dir.size() - 1));
    return std::uint32_t(dir.size() - 1);
  };
  // An edge far below a voxel on the sphere is not split (the maps never stretch one that much).
  const auto divisible = [&](std::uint32_t i, std::uint32_t j) { return length(dir[i] - dir[j]) * s.radius >= 1e-3; };
  struct Face {
    std::array<std::uint32_t, 3> v;
    std::array<std::uint32_t, 3> mid;  // the edges' midpoints when tested (kNone before)
  };
  const auto fails = [&](Face& f, int e) {
    const std::uint32_t i = f.v[std::size_t(e)], j = f.v[std::size_t((e + 1) % 3)];
    if (!divisible(i, j)) return false;
    if (length(dir[i] - dir[j]) * s.radius > kLongestEdge || length(at[i] - at[j]) > kLongestEdge) return true;
    f.mid[std::size_t(e)] = mid(i, j);
    // The midpoint's distance to the chord, not to the chord's midpoint: where the maps stretch
    // one end of an edge more than the other the midpoint slides along the surface, which the
    // triangles follow anyway.
    const Vec3 chord = at[j] - at[i], off = at[f.mid[std::size_t(e)]] - at[i];
    const double along = std::clamp(dot(off, chord) / dot(chord, chord), 0.0, 1.0);
    return length(off - chord * along) > kSagitta;
  };
  std::vector<Face> faces, work;
  for (const auto& f : ico) work.push_back({{std::uint32_t(f[0]), std::uint32_t(f[1]), std::uint32_t(f[2])}, {kNone, kNone, kNone}});
  const auto refine = [&] {
    while (!work.empty()) {
      Face f = work.back();
      work.pop_back();
      if (!fails(f, 0) && !fails(f, 1) && !fails(f, 2)) {
        faces.push_back(f);
        continue;
      }
      int longest = -1;
      double most = -1;
      for (int e = 0; e < 3; ++e) {
        const std::uint32_t i = f.v[std::size_t(e)], j = f.v[std::size_t((e + 1) % 3)];
        if (divisible(i, j) && length(at[i] - at[j]) > most) most = length(at[i] - at[j]), longest = e;
      }
      const std::uint32_t a = f.v[std::size_t(longest)], b = f.v[std::size_t((longest + 1) % 3)],
                          c = f.v[std::size_t((longest + 2) % 3)], m = mid(a, b);
      work.push_back({{a, m, c}, {kNone, kNone, kNone}});
      work.push_back({{m, b, c}, {kNone, kNone, kNone}});
      if (faces.size() + work.size() > kMostTriangles) throw std::length_error("carriedTriangles: too many triangles");
    }
  };
  refine();
  for (const WarpMap& map : s.maps) {
    std::vector<char> moved(at.size());
    for (std::size_t v = 0; v < at.size(); ++v) {
      const Vec3 p = map.forward(at[v]);
      moved[v] = !(p.x == at[v].x && p.y == at[v].y && p.z == at[v].z);
      at[v] = p;
    }
    ++applied;
    // A face is tested again where the map moved a corner or a tested midpoint.
    std::vector<Face> kept;
    for (const Face& f : faces) {
      bool touched = false;
      for (int e = 0; e < 3; ++e) touched = touched || moved[f.v[std::size_t(e)]] || (f.mid[std::size_t(e)] != kNone && moved[f.mid[std::size_t(e)]]);
      (touched ? work : kept).push_back(f);
    }
    faces.swap(kept);
    refine();
  }
  // Each face is cut into four at its edges' carried midpoints, which the tests above carried
  // already: the chords' error falls fourfold for nothing but the triangles' number.
  std::vector<std::array<Vec3, 3>> out;
  out.reserve(4 * faces.size());
  for (const Face& f : faces) {
    const std::array<std::uint32_t, 3>& v = f.v;
    const std::array<std::uint32_t, 3>& m = f.mid;
    if (m[0] == kNone || m[1] == kNone || m[2] == kNone) {
      out.push_back({at[v[0]], at[v[1]], at[v[2]]});
      continue;
    }
    out.push_back({at[v[0]], at[m[0]], at[m[2]]});
    out.push_back({at[m[0]], at[v[1]], at[m[1]]});
    out.push_back({at[m[2]], at[m[1]], at[v[2]]});
    out.push_back({at[m[0]], at[m[1]], at[m[2]]});
  }
  return out;
}

// The exact signed distance per voxel of a dims volume (x fastest), NaN farther than `reach`
// from the carried surface.
struct ExactField {
  Int3 dims;
  std::vector<float> d;
  float at(Int3 p) const { return d[std::size_t(p.x) + std::size_t(dims.x) * (std::size_t(p.y) + std::size_t(dims.y) * std::size_t(p.z))]; }
};

inline ExactField exactField(Int3 dims, const CarriedSphere& s, double reach) {
  const std::vector<std::array<Vec3, 3>> tris = carriedTriangles(s);
  // Triangles binned in cells of kCell voxels by their boxes (edges of at most a voxel: at most
  // eight cells each).
  constexpr int kCell = 2;
  const Int3 cells{dims.x / kCell + 1, dims.y / kCell + 1, dims.z / kCell + 1};
  const auto cellIndex = [&](int x, int y, int z) { return std::size_t(x) + std::size_t(cells.x) * (std::size_t(y) + std::size_t(cells.y) * std::size_t(z)); };
  const auto cellOf = [&](double c, int a) { return std::clamp(int(std::floor(c / kCell)), 0, cells[a] - 1); };
  std::vector<std::uint32_t> start(std::size_t(cells.x) * cells.y * cells.z + 1, 0), items;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint32_t> fill(pass ? start : std::vector<std::uint32_t>{});
    for (std::size_t i = 0; i < tris.size(); ++i) {
      Int3 lo, hi;
      for (int a = 0; a < 3; ++a) {
        const double mn = std::min({tris[i][0][a], tris[i][1][a], tris[i][2][a]});
        const double mx = std::max({tris[i][0][a], tris[i][1][a], tris[i][2][a]});
        lo[a] = cellOf(mn, a), hi[a] = cellOf(mx, a);
      }
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y)
          for (int x = lo.x; x <= hi.x; ++x) {
            if (pass == 0) ++start[cellIndex(x, y, z) + 1];
            else items[fill[cellIndex(x, y, z)]++] = std::uint32_t(i);
          }
    }
    if (pass == 0) {
      for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
      items.resize(start.back());
    }
  }
  ExactField out{dims, std::vector<float>(std::size_t(dims.x) * dims.y * dims.z, std::numeric_limits<float>::quiet_NaN())};
  // The cells within reach of a cell that holds triangles.
  const int grow = int(std::ceil(reach / kCell)) + 1;
  std::vector<char> near(start.size() - 1, 0);
  for (int z = 0; z < cells.z; ++z)
    for (int y = 0; y < cells.y; ++y)
      for (int x = 0; x < cells.x; ++x) {
        if (start[cellIndex(x, y, z) + 1] == start[cellIndex(x, y, z)]) continue;
        for (int k = std::max(0, z - grow); k <= std::min(cells.z - 1, z + grow); ++k)
          for (int j = std::max(0, y - grow); j <= std::min(cells.y - 1, y + grow); ++j)
            for (int i = std::max(0, x - grow); i <= std::min(cells.x - 1, x + grow); ++i) near[cellIndex(i, j, k)] = 1;
      }
  std::vector<std::pair<double, std::size_t>> candidates;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const int cx = x / kCell, cy = y / kCell, cz = z / kCell;
        if (!near[cellIndex(cx, cy, cz)]) continue;
        const Vec3 p{double(x), double(y), double(z)};
        // The cells within reach, nearest first.
        candidates.clear();
        for (int k = std::max(0, cz - grow); k <= std::min(cells.z - 1, cz + grow); ++k)
          for (int j = std::max(0, cy - grow); j <= std::min(cells.y - 1, cy + grow); ++j)
            for (int i = std::max(0, cx - grow); i <= std::min(cells.x - 1, cx + grow); ++i) {
              const std::size_t c = cellIndex(i, j, k);
              if (start[c + 1] == start[c]) continue;
              double gap2 = 0;
              const int cc[3] = {i, j, k};
              for (int a = 0; a < 3; ++a) {
                const double lo = cc[a] * kCell, hi = lo + kCell;
                const double g = p[a] < lo ? lo - p[a] : p[a] > hi ? p[a] - hi : 0;
                gap2 += g * g;
              }
              if (gap2 <= reach * reach) candidates.emplace_back(gap2, c);
            }
        std::sort(candidates.begin(), candidates.end());
        double best2 = reach * reach;
        bool found = false;
        for (const auto& [gap2, c] : candidates) {
          if (gap2 > best2) break;
          for (std::uint32_t k = start[c]; k < start[c + 1]; ++k) {
            const auto& t = tris[items[k]];
            const Vec3 q = closestOnTriangle(p, t[0], t[1], t[2]);
            const double e2 = dot(q - p, q - p);
            if (e2 <= best2) best2 = e2, found = true;
          }
        }
        if (!found) continue;
        const double dist = std::sqrt(best2);
        out.d[std::size_t(x) + std::size_t(dims.x) * (std::size_t(y) + std::size_t(dims.y) * std::size_t(z))] =
            float(s.inside(p) ? -dist : dist);
      }
  return out;
}

// The exact field as a volume of ours' dimensions and band: the exact distance where it is
// known (clamped to the band as every volume is), ours' sign times the band elsewhere (farther
// than `reach` from the surface, where nothing the measures read depends on the value).
inline Volume exactVolume(const Volume& ours, const ExactField& e) {
  const Int3 n = ours.dims();
  const float band = ours.band();
  std::vector<float> values(std::size_t(n.x) * n.y * n.z);
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const float d = e.at({x, y, z});
        const std::size_t i = std::size_t(x) + std::size_t(n.x) * (std::size_t(y) + std::size_t(n.y) * std::size_t(z));
        values[i] = d == d ? std::clamp(d, -band, band) : ours.at(x, y, z) < 0 ? -band : band;
      }
  Volume v(n, band);
  v.scatter(v.domain(), values.data(), v.domain());
  return v;
}

// |ours - exact| over the voxels where |exact| < band: the largest, the mean, and how many.
struct DistanceError {
  double max = 0, mean = 0;
  std::size_t voxels = 0;
};

inline DistanceError distanceError(const Volume& ours, const ExactField& e) {
  DistanceError out;
  double sum = 0;
  const Int3 n = ours.dims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const float d = e.at({x, y, z});
        if (!(std::fabs(d) < ours.band())) continue;
        const double err = std::fabs(double(ours.at(x, y, z)) - double(d));
        out.max = std::max(out.max, err);
        sum += err;
        ++out.voxels;
      }
  out.mean = out.voxels ? sum / double(out.voxels) : 0;
  return out;
}

}  // namespace marzipan::test_warp
