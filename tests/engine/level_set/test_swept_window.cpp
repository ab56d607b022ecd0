// A stroke's window search (server/engine/level_set/swept_window.hpp): rows whose dabs are out of
// order along x give the pinned field through the SSE2 lanes, the AVX2 lanes and (in
// engine_scalar_tests) the scalar search.
#include <catch2/catch.hpp>

#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "engine/simd_width.hpp"
#include "../support.hpp"

using namespace marzipan;

namespace {

// Recorded 2026-11-25 before the window search began to read a row's dabs where all the
// stroke's dabs are when they are consecutive along x (and from arrays of the row's own when
// not), four at a time with AVX2: the same field bit for bit, on 1 and 2 threads and with both
// widths. Zigzag strokes (dabs alternately above and below a line, so the rows near its edges
// hold every other dab), with memory, plain and with heights, their dabs with and without
// normals (lanes and the scalar search), and a stroke whose memory crosses it.
std::vector<std::string> zigzagStrokes(ThreadPool& pool) {
  Volume v = makeSphere({80, 80, 80}, {40, 40, 40}, 28);
  std::mt19937 rng(37);
  std::uniform_real_distribution<double> unit(-1, 1), weight(0.3, 1.0), radius(4, 9);
  std::vector<std::string> digests;
  for (int i = 0; i < 12; ++i) {
    const double r = radius(rng);
    const Vec3 dir = normalized(Vec3{unit(rng), unit(rng), unit(rng)});
    const Vec3 side = normalized(cross(dir, normalized(Vec3{unit(rng), unit(rng), unit(rng)})));
    const Vec3 start = Vec3{40, 40, 40} + normalized(Vec3{unit(rng), unit(rng), unit(rng)}) * 28.0;
    std::vector<StrokeDab> path;
    for (int k = 0; k < 18; ++k) {
      const Vec3 c = start + dir * (0.3 * r * (k - 9)) + side * (k % 2 ? 0.6 * r : -0.6 * r);
      path.push_back({c, weight(rng), i % 3 == 2 ? Vec3{} : normalized(c - Vec3{40, 40, 40})});
    }
    const std::span<const StrokeDab> all(path);
    const std::size_t split = 5 + std::size_t(i % 4);
    StrokeSettings st{i % 2 ? Brush::RemoveBlob : Brush::AddBlob, r, weight(rng)};
    if (i % 4 >= 2) st.height = std::min(r / 2, 3.5);
    if (i % 6 == 5) st.tool = Brush::Smooth, st.height.reset();
    applyStroke(v, st, all.first(split), {}, pool);
    applyStroke(v, st, all.subspan(split), all.first(split), pool);
    // The first dabs again, with the rest as memory: the memory lies on both sides.
    applyStroke(v, st, all.first(split), all.subspan(split), pool);
    if (i % 3 == 2) digests.push_back(digestHex(v));
  }
  return digests;
}

// Re-pinned 2026-11-25 (afternoon) when a local tool's redistance was cut to the box of the
// voxels its evolve moved (a voxel whose foot point lies past the ROI, or where a stroke's
// memory already reaches its window, does not move, and the band around it keeps its bits):
// Fig. 7.13 mean 0.01248 -> 0.01231 (max 0.292893 both), the sphere's cap 0.02116 / 0.000899
// -> 0.02119 / 0.000911, the crease 0.295769 both. Re-pinned 2026-11-29 when a dab without a
// normal in a stroke with a height (inflate's) began to read its window at the foot point
// projected along the voxel's own normal onto the plane through the dab's centre, unclamped
// (level_set.hpp, strokes): the strokes i = 2 and 11 have such dabs; the pinned strokes of
// test_kernels.cpp, whose dabs all have normals, kept their digests. Re-pinned 2026-11-29 with
// the direct near voxels of the redistance (redistance.hpp, RedistanceOptions::direct; the
// accuracy figures at test_kernels.cpp's first pinned test), and again with its box cut to the
// voxels an advection moved by more than 0.01 vu (stroke.cpp, kLeastMove; the same figures), and
// when an application that moved no voxel by more than that went back to the box as before.
const std::vector<std::string> kZigzagStrokes = {
    "e65a322580563dba", "b0b7d08d49ff5872", "54a66c169dae933f", "d7f84e932298e4ea"};

}  // namespace

TEST_CASE("strokes whose rows hold their dabs out of order along x are pinned", "[level_set][determinism][pinned][stroke]") {
  const test::WidestWidthAtExit restore;
  simd_width::limitWidth(simd_width::Width::Sse2);
  ThreadPool one(1), two(2);
  CHECK(zigzagStrokes(one) == kZigzagStrokes);
  CHECK(zigzagStrokes(two) == kZigzagStrokes);
}

TEST_CASE("strokes whose rows hold their dabs out of order along x give the pinned field with AVX2",
          "[level_set][determinism][pinned][stroke][avx2]") {
  if (!test::avx2OrSkipped()) return;
  ThreadPool one(1), two(2);
  CHECK(zigzagStrokes(one) == kZigzagStrokes);
  CHECK(zigzagStrokes(two) == kZigzagStrokes);
}
