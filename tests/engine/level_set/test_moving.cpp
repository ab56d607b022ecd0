// The motion driver (server/engine/level_set/moving.cpp) and the listing's pieces on the pool:
// the same field on any number of threads, with smoothing's sub-steps taken by threads in
// whatever order their pieces become ready.
#include <catch2/catch.hpp>

#include <cstdint>
#include <random>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

TEST_CASE("results are bit-identical on 1 and 2 threads", "[level_set][determinism]") {
  // 160^3 is two chunks per axis, so global operations run chunks in parallel.
  auto run = [](ThreadPool& pool) {
    Volume v = makeSolid(SolidKind::Pig, {160, 160, 160}, Volume::kDefaultBand, pool);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> pos(50, 110), radius(3, 12), strength(0.1, 1.0);
    for (int i = 0; i < 50; ++i) {
      const BrushParams p{{pos(rng), pos(rng), pos(rng)}, radius(rng), strength(rng)};
      switch (i % 7) {
        case 0: addBlob(v, p, pool); break;
        case 1: removeBlob(v, p, pool); break;
        case 2: smooth(v, p, pool); break;
        case 3: sharpen(v, p, pool); break;
        case 4: if (i % 21 == 4) dilate(v, 1, pool); else addBlob(v, p, pool); break;
        case 5: if (i % 35 == 5) meanCurvatureFlow(v, 1, 1, pool); else smooth(v, p, pool); break;
        case 6: if (i % 42 == 6) erode(v, 0.5, pool); else removeBlob(v, p, pool); break;
      }
    }
    return digest(v);
  };
  ThreadPool one(1), two(2);
  CHECK(run(one) == run(two));
}

TEST_CASE("smoothing's sub-steps over a large region give the same field on 1 to 3 threads",
          "[level_set][determinism][smooth]") {
  // ROI 60 on a radius-40 sphere: ~27k band voxels in some fifty pieces of z-slices, which the
  // threads take in whatever order they become ready; sharpening and a stroke of smoothing dabs
  // (pieces with gaps between them) too.
  auto run = [](ThreadPool& pool) {
    Volume v = makeSphere({112, 112, 112}, {56, 56, 56}, 40);
    std::vector<std::uint64_t> digests;
    for (int i = 0; i < 3; ++i) {
      smooth(v, {{56, 56 + 10.0 * i, 96}, 30, 1}, pool);
      digests.push_back(digest(v));
    }
    sharpen(v, {{56, 16, 56}, 30, 0.5}, pool);
    std::vector<StrokeDab> dabs;
    for (int k = 0; k < 8; ++k) dabs.push_back({{16.0 + 8 * k, 56, 96}, 1.0});
    applyStroke(v, {Brush::Smooth, 12, 1}, dabs, {}, pool);
    digests.push_back(digest(v));
    return digests;
  };
  ThreadPool one(1), two(2), three(3);
  const std::vector<std::uint64_t> serial = run(one);
  CHECK(run(two) == serial);
  CHECK(run(three) == serial);
  CHECK(run(two) == serial);
}
