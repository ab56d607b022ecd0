// Mesh scenarios: marching cubes of a sphere (OpenVDB volumeToMesh takes 125 ms on the full
// size), and decimation of that mesh to a quarter of its triangles (the whole of decimateMesh:
// weld, meshoptimizer's collapses, edge flips, vertex cache/fetch order and the measured
// error). Sizes in vu; one thread unless --threads says otherwise.
#include <vector>

#include "bench.hpp"
#include "engine/decimate.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"

namespace marzipan::bench {

MARZIPAN_BENCH("mesh_mc") {
  const int n = opt.quick ? 64 : 256;
  const double r = opt.quick ? 25 : 100;
  const Volume vol = makeSphere({n, n, n}, {n / 2.0 - 0.3, n / 2.0 + 0.2, n / 2.0 - 0.1}, r);
  ThreadPool pool(1);
  Mesh mesh;
  const Timing t = measure(opt.quick ? 1 : 9, [&] { mesh = extractMesh(vol, pool); });
  emit("mesh_mc", 1, t,
       {{"size", n}, {"radius", r}, {"triangles", mesh.triangleCount()}, {"vertices", mesh.vertexCount()}});
}

MARZIPAN_BENCH("mesh_decimate") {
  const int n = opt.quick ? 64 : 256;
  const double r = opt.quick ? 25 : 100;
  const std::size_t budget = opt.quick ? 6000 : 100000;
  const Volume vol = makeSphere({n, n, n}, {n / 2.0, n / 2.0, n / 2.0}, r);
  ThreadPool pool(opt.threads);
  const Mesh full = extractMesh(vol, pool);
  DecimateResult result;
  const Timing t = measure(opt.quick ? 1 : 5, [&] { result = decimateMesh(full, vol, {budget, std::nullopt}, pool); });
  emit("mesh_decimate", opt.threads, t,
       {{"size", n},
        {"radius", r},
        {"source_triangles", result.sourceTriangles},
        {"triangles", result.mesh.triangleCount()},
        {"max_error_vu", result.maxError}});
}

}  // namespace marzipan::bench
