// Decimation through Debian's libmeshoptimizer (conventions in decimate.hpp).
#include "decimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <meshoptimizer.h>

#include "errors.hpp"

namespace marzipan {

namespace {

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
    }
  }
  meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), vertices);
  // Vertices in first-use order, unused ones dropped; normals follow their vertices.
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
  r.maxError = surfaceDeviation(r.mesh, vol, pool);
  return r;
}

double surfaceDeviation(const Mesh& m, const Volume& vol, ThreadPool& pool) {
  constexpr int kSteps = 4;
  constexpr std::size_t kChunk = 4096;  // triangles per task; the maximum does not depend on it
  const std::size_t chunks = (m.triangleCount() + kChunk - 1) / kChunk;
  std::vector<double> worst(chunks, 0.0);
  pool.parallelFor(chunks, [&](std::size_t c) {
    double w = 0;
    for (std::size_t t = c * kChunk; t < std::min(m.triangleCount(), (c + 1) * kChunk); ++t) {
      const Vec3 a = m.position(m.indices[3 * t]), b = m.position(m.indices[3 * t + 1]),
                 d = m.position(m.indices[3 * t + 2]);
      for (int i = 0; i <= kSteps; ++i)
        for (int j = 0; i + j <= kSteps; ++j) {
          const double u = double(i) / kSteps, v = double(j) / kSteps;
          w = std::max(w, std::fabs(vol.sample(a + (b - a) * u + (d - a) * v)));
        }
    }
    worst[c] = w;
  });
  return worst.empty() ? 0.0 : *std::max_element(worst.begin(), worst.end());
}

}  // namespace marzipan
