#include <catch2/catch.hpp>

#include <cmath>

#include "engine/dense_grid.hpp"
#include "engine/progress.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

namespace {

std::size_t mismatches(const DenseGrid& g, const Volume& v) {
  std::size_t wrong = 0, i = 0;
  for (int z = g.box.lo.z; z < g.box.hi.z; ++z)
    for (int y = g.box.lo.y; y < g.box.hi.y; ++y)
      for (int x = g.box.lo.x; x < g.box.hi.x; ++x, ++i) wrong += !(g.v[i] == v.at(x, y, z));
  return wrong;
}

}  // namespace

// A large box is gathered in slabs of brick layers on the pool (kParallelGatherVoxels): every
// voxel as at() reads it, also where the box reaches past the domain and the slabs are cut.
TEST_CASE("gatherFrom reads every voxel as at() does on 1, 2 and 3 threads, into a reused grid",
          "[dense_grid][threads]") {
  const Volume v = makeSphere({90, 83, 77}, {44.3, 41.1, 37.6}, 30);
  const Box large{{-5, -6, -11}, {95, 70, 85}};  // z from -11: the first and last slabs are cut
  REQUIRE(large.voxels() >= DenseGrid::kParallelGatherVoxels);
  const Box small{{20, 21, 3}, {41, 30, 44}};
  for (const int threads : {1, 2, 3}) {
    INFO(threads << " threads");
    ThreadPool pool(threads);
    DenseGrid g;
    for (const Box& b : {large, small, large}) {
      g.gatherFrom(v, b, ProgressShare{}, pool);
      CHECK(g.box == b);
      CHECK(g.v.size() == std::size_t(b.voxels()));
      CHECK(mismatches(g, v) == 0);
    }
    // With a progress: the whole share is counted, and a cancelled one stops the gather.
    Progress progress;
    g.gatherFrom(v, large, ProgressShare{&progress, 1}, pool);
    CHECK(progress.fraction() == Approx(1.0));
    CHECK(mismatches(g, v) == 0);
    Progress cancelled;
    cancelled.cancel();
    CHECK_THROWS_AS(g.gatherFrom(v, large, ProgressShare{&cancelled, 1}, pool), Cancelled);
  }
}
