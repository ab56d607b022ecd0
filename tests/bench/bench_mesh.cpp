// Mesh scenarios: marching cubes of a sphere (OpenVDB volumeToMesh takes 125 ms on the full
// size). Sizes in vu; one thread unless --threads says otherwise.
#include <vector>

#include "bench.hpp"
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

}  // namespace marzipan::bench
