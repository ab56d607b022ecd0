// Decimation through Debian's libmeshoptimizer (conventions in decimate.hpp).
#include "decimate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <meshoptimizer.h>

#include "errors.hpp"

namespace marzipan {

namespace {

// The largest |d| at 15 points of the triangle (its corners and a barycentric grid of step 1/4).
double triangleDeviation(Vec3 a, Vec3 b, Vec3 c, const Volume& vol) {
  constexpr int kSteps = 4;
  double w = 0;
  for (int i = 0; i <= kSteps; ++i)
    for (int j = 0; i + j <= kSteps; ++j) {
      const double u = double(i) / kSteps, v = double(j) / kSteps;
      w = std::max(w, std::fabs(vol.sample(a + (b - a) * u + (c - a) * v)));
    }
  return w;
}

// meshoptimizer 0.18 collapses edges without testing the link condition, so on a closed mesh a
// collapse can fold two triangles onto the same three vertices with opposite windings (a fin of
// zero volume) and make its three edges non-manifold. Removing both triangles of each such
// pair gives each edge back its two other triangles.
void dropFins(std::vector<unsigned>& indices) {
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> byCorners;
  auto key = [&](std::size_t t) {
    unsigned v[3] = {indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]};
    std::sort(v, v + 3);
    // Three 21-bit fields would overflow past 2M vertices: hash the triple, confirm below.
    return (std::uint64_t(v[0]) * 0x9E3779B97F4A7C15ull) ^ (std::uint64_t(v[1]) * 0xC2B2AE3D27D4EB4Full) ^ std::uint64_t(v[2]);
  };
  const std::size_t triangles = indices.size() / 3;
  for (std::size_t t = 0; t < triangles; ++t) byCorners[key(t)].push_back(t);
  std::vector<bool> drop(triangles, false);
  auto sameCorners = [&](std::size_t a, std::size_t b) {
    unsigned x[3] = {indices[3 * a], indices[3 * a + 1], indices[3 * a + 2]};
    unsigned y[3] = {indices[3 * b], indices[3 * b + 1], indices[3 * b + 2]};
    std::sort(x, x + 3), std::sort(y, y + 3);
    return std::equal(x, x + 3, y);
  };
  for (const auto& [k, list] : byCorners)
    for (std::size_t i = 0; i < list.size(); ++i)
      for (std::size_t j = i + 1; j < list.size(); ++j)
        if (!drop[list[i]] && !drop[list[j]] && sameCorners(list[i], list[j])) drop[list[i]] = drop[list[j]] = true;
  std::size_t kept = 0;
  for (std::size_t t = 0; t < triangles; ++t)
    if (!drop[t]) {
      for (int k = 0; k < 3; ++k) indices[3 * kept + std::size_t(k)] = indices[3 * t + std::size_t(k)];
      ++kept;
    }
  indices.resize(3 * kept);
}

// meshoptimizer's quadric measures how far a kept vertex lies from the planes of the triangles
// it replaces, which on a curved surface is about nothing however long the new edges get: the
// simplified mesh has a few slivers whose long edge sags across the surface (0.126 vu on the
// radius-100 sphere at 100k triangles). An edge is flipped to the quad's other diagonal when
// that one is shorter, the two new triangles face the way the old ones did, and they lie closer
// to the field's zero set (triangleDeviation) than the old two: the long chords go without a
// change to the vertices or the triangle count. Every flip shortens an edge, so the passes end.
void flipLongEdges(std::vector<unsigned>& indices, const float* positions, const Volume& vol) {
  constexpr int kPasses = 16;
  constexpr double kMinFacing = 0.5;  // cos 60 degrees between a new triangle's normal and the old pair's
  auto pos = [&](unsigned v) { return Vec3{positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]}; };
  auto key = [](unsigned a, unsigned b) { return a < b ? (std::uint64_t(a) << 32) | b : (std::uint64_t(b) << 32) | a; };
  auto normalOf = [&](unsigned a, unsigned b, unsigned c) { return cross(pos(b) - pos(a), pos(c) - pos(a)); };
  const std::size_t triangles = indices.size() / 3;
  // Undirected edge -> its two triangles (a closed manifold mesh has exactly two).
  std::unordered_map<std::uint64_t, std::array<std::uint32_t, 2>> edges;
  edges.reserve(indices.size());
  for (std::size_t t = 0; t < triangles; ++t)
    for (int k = 0; k < 3; ++k) {
      auto [it, added] = edges.try_emplace(key(indices[3 * t + k], indices[3 * t + (k + 1) % 3]),
                                           std::array<std::uint32_t, 2>{std::uint32_t(t), ~0u});
      if (!added) it->second[1] = it->second[1] == ~0u ? std::uint32_t(t) : ~1u;  // ~1u: more than two
    }
  auto replace = [&](unsigned a, unsigned b, std::uint32_t from, std::uint32_t to) {
    auto& pair = edges.at(key(a, b));
    pair[pair[0] == from ? 0 : 1] = to;
  };
  for (int pass = 0; pass < kPasses; ++pass) {
    std::size_t flips = 0;
    for (std::size_t t1 = 0; t1 < triangles; ++t1)
      for (int k = 0; k < 3; ++k) {
        unsigned* x = &indices[3 * t1];
        const unsigned a = x[k], b = x[(k + 1) % 3], c = x[(k + 2) % 3];
        const auto found = edges.find(key(a, b));
        if (found == edges.end() || found->second[1] >= ~1u) continue;
        const std::uint32_t t2 = found->second[0] == t1 ? found->second[1] : found->second[0];
        unsigned* y = &indices[3 * std::size_t(t2)];
        // t2 runs b -> a; d is its third vertex.
        int j = 0;
        while (j < 3 && !(y[j] == b && y[(j + 1) % 3] == a)) ++j;
        if (j == 3) continue;
        const unsigned d = y[(j + 2) % 3];
        if (c == d || edges.count(key(c, d)) || edges.at(key(a, d))[1] == ~1u || edges.at(key(b, c))[1] == ~1u) continue;
        if (length(pos(c) - pos(d)) >= length(pos(a) - pos(b))) continue;
        const Vec3 before = normalized(normalOf(a, b, c) + normalOf(b, a, d));
        const Vec3 n1 = normalOf(a, d, c), n2 = normalOf(d, b, c);
        if (!(dot(normalized(n1), before) > kMinFacing && dot(normalized(n2), before) > kMinFacing)) continue;
        if (std::max(triangleDeviation(pos(a), pos(d), pos(c), vol), triangleDeviation(pos(d), pos(b), pos(c), vol)) >=
            std::max(triangleDeviation(pos(a), pos(b), pos(c), vol), triangleDeviation(pos(b), pos(a), pos(d), vol)))
          continue;
        // (a, b, c) + (b, a, d) -> (a, d, c) + (d, b, c): the quad a, d, b, c keeps its winding.
        x[0] = a, x[1] = d, x[2] = c;
        y[0] = d, y[1] = b, y[2] = c;
        edges.erase(key(a, b));
        edges.emplace(key(c, d), std::array<std::uint32_t, 2>{std::uint32_t(t1), t2});
        replace(a, d, t2, std::uint32_t(t1));
        replace(b, c, std::uint32_t(t1), t2);
        ++flips;
        break;  // t1's corners changed: its other edges are visited in the next pass
      }
    if (!flips) break;
  }
}

}  // namespace

DecimateResult decimateMesh(const Mesh& m, const Volume& vol, const DecimateOptions& options, ThreadPool& pool) {
  if (options.maxTriangles && *options.maxTriangles < 1)
    throw EngineError(ErrorKind::InvalidArgument, "max_triangles", "must be at least 1");
  if (options.maxError && !(std::isfinite(*options.maxError) && *options.maxError > 0))
    throw EngineError(ErrorKind::InvalidArgument, "max_error", "must be a finite number of vu above 0");
  const std::size_t vertices = m.vertexCount();
  DecimateResult r;
  r.sourceTriangles = m.triangleCount();
  std::vector<unsigned> indices(m.indices.begin(), m.indices.end());
  // Marching cubes gives a voxel with d = 0 exactly one vertex per crossed edge, all at the same
  // point. Welded by position, those become one vertex (the one first used) and the zero-area
  // triangles between them vanish; otherwise the simplifier sees holes there.
  if (!indices.empty()) {
    std::vector<unsigned> weld(vertices);
    meshopt_generateVertexRemap(weld.data(), nullptr, vertices, m.positions.data(), vertices, 3 * sizeof(float));
    // weld maps to a compacted numbering; map back to the first source vertex of each position.
    std::vector<unsigned> first(vertices, ~0u);
    for (std::size_t v = 0; v < vertices; ++v)
      if (first[weld[v]] == ~0u) first[weld[v]] = unsigned(v);
    std::vector<unsigned> welded;
    welded.reserve(indices.size());
    for (std::size_t t = 0; t < indices.size(); t += 3) {
      const unsigned a = first[weld[indices[t]]], b = first[weld[indices[t + 1]]], c = first[weld[indices[t + 2]]];
      if (a == b || b == c || a == c) continue;
      welded.insert(welded.end(), {a, b, c});
    }
    indices = std::move(welded);
  }

  if ((options.maxTriangles || options.maxError) && !indices.empty()) {
    const bool budgetMet = options.maxTriangles && *options.maxTriangles >= m.triangleCount();
    if (!budgetMet) {
      // meshoptimizer's error is relative to the mesh's extent; without a bound, any error.
      const float scale = meshopt_simplifyScale(m.positions.data(), vertices, 3 * sizeof(float));
      const float relative = options.maxError && scale > 0 ? float(*options.maxError / scale) : 1.0f;
      const std::size_t target = options.maxTriangles ? 3 * *options.maxTriangles : 0;
      std::vector<unsigned> out(indices.size());
      out.resize(meshopt_simplify(out.data(), indices.data(), indices.size(), m.positions.data(), vertices,
                                  3 * sizeof(float), target, relative, 0, nullptr));
      indices = std::move(out);
      dropFins(indices);
      flipLongEdges(indices, m.positions.data(), vol);
    }
  }
  meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), vertices);
  // Vertices in first-use order, unused ones dropped; normals and colours follow their vertices.
  std::vector<unsigned> remap(vertices);
  const std::size_t kept = meshopt_optimizeVertexFetchRemap(remap.data(), indices.data(), indices.size(), vertices);
  r.mesh.indices.resize(indices.size());
  meshopt_remapIndexBuffer(r.mesh.indices.data(), indices.data(), indices.size(), remap.data());
  r.mesh.positions.resize(3 * kept);
  meshopt_remapVertexBuffer(r.mesh.positions.data(), m.positions.data(), vertices, 3 * sizeof(float), remap.data());
  if (!m.normals.empty()) {
    r.mesh.normals.resize(3 * kept);
    meshopt_remapVertexBuffer(r.mesh.normals.data(), m.normals.data(), vertices, 3 * sizeof(float), remap.data());
  }
  if (!m.colors.empty()) {
    r.mesh.colors.resize(3 * kept);
    meshopt_remapVertexBuffer(r.mesh.colors.data(), m.colors.data(), vertices, 3, remap.data());
  }
  r.maxError = surfaceDeviation(r.mesh, vol, pool);
  return r;
}

double surfaceDeviation(const Mesh& m, const Volume& vol, ThreadPool& pool) {
  constexpr std::size_t kChunk = 4096;  // triangles per task; the maximum does not depend on it
  const std::size_t chunks = (m.triangleCount() + kChunk - 1) / kChunk;
  std::vector<double> worst(chunks, 0.0);
  pool.parallelFor(chunks, [&](std::size_t c) {
    double w = 0;
    for (std::size_t t = c * kChunk; t < std::min(m.triangleCount(), (c + 1) * kChunk); ++t)
      w = std::max(w, triangleDeviation(m.position(m.indices[3 * t]), m.position(m.indices[3 * t + 1]),
                                        m.position(m.indices[3 * t + 2]), vol));
    worst[c] = w;
  });
  return worst.empty() ? 0.0 : *std::max_element(worst.begin(), worst.end());
}

}  // namespace marzipan
