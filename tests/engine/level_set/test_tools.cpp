// The brush tools (server/engine/level_set/tools.cpp), one dab at a time: the thesis's
// distance-field preservation (section 7.6.0.4, Fig. 7.13; docs/method.md), topology changes, the
// region of interest, undo data, and every deformative tool's refusal of bad parameters.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "engine/errors.hpp"
#include "engine/image_io.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/raycast.hpp"
#include "engine/redistance.hpp"
#include "engine/shapes.hpp"
#include "engine/solids.hpp"
#include "test_paths.hpp"

using namespace marzipan;

TEST_CASE("800 random add-blob and smoothing applications keep a distance field (thesis 7.6.0.4)",
          "[level_set][preservation]") {
  // A cube in 64^3; the tools work on its +x face (x = 52). The error is measured on the middle
  // of the face, which every application's window covers evenly (the thesis's condition of
  // "little high curvature"); where the sculpted patch meets the untouched cube edges the
  // crease is sharp and central differences read up to 0.1-0.25 there.
  Volume v = makeBox({64, 64, 64}, {32, 32, 32}, {20, 20, 20});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(22, 42), radius(4, 8), strength(0.2, 1.0);
  for (int i = 0; i < 800; ++i) {
    const Vec3 c{52, pos(rng), pos(rng)};
    const BrushParams p{c, radius(rng), strength(rng)};
    if (i % 2 == 0) {
      addBlob(v, p);
    } else {
      smooth(v, p);
    }
  }
  const GradientError e = gradientError(v, {{40, 24, 24}, {64, 40, 40}});
  INFO("max " << e.max << " mean " << e.mean << " over " << e.voxels << " voxels");
  CHECK(e.voxels > 400);
  CHECK(e.max <= 0.05);  // thesis: 0.07
  CHECK(e.mean <= 0.01);
  CHECK(boundingBox(v).hi.x > 53);  // the face really was sculpted outward
}

// The field stays a distance field beyond the ROI (DESIGN: a local tool leaves the whole band
// a distance field to the new surface). Every figure is over the whole volume.

TEST_CASE("Fig. 7.13: 400 add blob + 400 smoothing on a cube face leave no error above the cube's edges",
          "[level_set][preservation][roi]") {
  // makeSolid's box in 64^3: faces at 15.5 and 47.5. The tools' centres are random points of
  // the +x face whose ROIs (radius 4) stay off the cube's edges, so the edges' own reading
  // (1 - 1/sqrt 2 = 0.293 for a right angle) is the highest a distance field may show.
  Volume v = makeSolid(SolidKind::Box, {64, 64, 64});
  const GradientError edges = gradientError(v);
  REQUIRE(edges.max == Approx(1 - std::sqrt(0.5)).margin(1e-3));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(22, 41);
  for (int i = 0; i < 800; ++i) {
    const BrushParams p{{47.5, pos(rng), pos(rng)}, 4, 0.5};
    if (i % 2 == 0) {
      addBlob(v, p);
    } else {
      smooth(v, p);
    }
  }
  const GradientError e = gradientError(v);
  const Camera camera{{110, 80, 70}, {32, 32, 32}, {0, 1, 0}, 40, 384, 384};
  const Frame f = render(v, camera, Shading::GradientError, ThreadPool::serial());
  std::filesystem::create_directories(marzipan::test_paths::kEngineArtifacts);
  const std::string png = std::string(marzipan::test_paths::kEngineArtifacts) + "/fig7_13_cube_face_gradient_error.png";
  const auto bytes = encodePng(f.rgb, f.width, f.height);
  std::ofstream(png, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  INFO("before: max " << edges.max << "; after: max " << e.max << " mean " << e.mean << " over " << e.voxels
                      << " voxels; picture " << png);
  CHECK(boundingBox(v).hi.x > 49);  // the face really was sculpted outward
  CHECK(e.max <= edges.max + 0.05);
  CHECK(e.mean <= 0.02);
}

TEST_CASE("add blob and smoothing on a sphere's cap keep a distance field everywhere", "[level_set][preservation][roi]") {
  // Bumps pile up on the cap until they reach their ROIs' faces (with the band left at the old
  // surface there, the error read 1.03); smoothing at full strength keeps the surface itself
  // smooth, so whatever error remains is the field's.
  Volume v = makeSphere({64, 64, 64}, {32, 32, 32}, 24);
  std::mt19937 rng(7);
  std::normal_distribution<double> spread(0, 0.4);
  for (int i = 0; i < 800; ++i) {
    const Vec3 c = Vec3{32, 32, 32} + normalized(Vec3{spread(rng), spread(rng), 1}) * 24.0;
    if (i % 2 == 0) {
      addBlob(v, {c, 5, 0.5});
    } else {
      smooth(v, {c, 5, 1});
    }
  }
  const GradientError e = gradientError(v);
  INFO("max " << e.max << " mean " << e.mean << " over " << e.voxels << " voxels");
  CHECK(boundingBox(v).hi.z > 58);
  CHECK(e.max <= 0.05);
  CHECK(e.mean <= 0.005);
}

TEST_CASE("thirty add blobs at one centre: the bump meets its ROI's face in a crease, not a jump",
          "[level_set][preservation][roi]") {
  // The bump grows until its top reaches the ROI's face (the surface moves only inside the
  // ROI); the band above that face must follow it. Before, it kept the distances to the old
  // surface and the field jumped there (max error 0.4-1.0).
  Volume v = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  for (int i = 0; i < 30; ++i) addBlob(v, {{32, 52.3, 32.2}, 6, 1});
  const GradientError e = gradientError(v);
  // The crease itself is the surface's: a whole-volume redistance of the same zero set reads
  // the same (0.293 here; 0.28-0.30 with the centre shifted by fractions of a voxel).
  Volume fresh = v;
  redistanceVolume(fresh, ThreadPool::serial());
  const GradientError f = gradientError(fresh);
  INFO("max " << e.max << " mean " << e.mean << "; redistanced: max " << f.max);
  CHECK(boundingBox(v).hi.y > 57);
  CHECK(e.max <= 0.30);  // a right-angle crease reads 0.293
  CHECK(e.max <= f.max + 0.01);
  CHECK(e.mean <= 0.005);
}

TEST_CASE("remove blob drills a hole through a slab", "[level_set][topology]") {
  Volume v = makeBox({48, 48, 48}, {23.5, 23.5, 23.5}, {3, 16, 16});  // slab x in [20.5, 26.5]
  REQUIRE(v.at(23, 23, 23) < 0);
  for (int i = 0; i < 8; ++i) {
    removeBlob(v, {{20.5, 23.5, 23.5}, 6, 1});
    removeBlob(v, {{26.5, 23.5, 23.5}, 6, 1});
  }
  for (int x = 0; x < 48; ++x) CHECK(v.at(x, 23, 23) > 0);
  CHECK(countComponents(v) == 1);
  CHECK(v.at(23, 8, 8) < 0);  // the rest of the slab stands
}

TEST_CASE("two add-blob prongs grow together into one", "[level_set][topology]") {
  Volume v = makeBox({48, 48, 48}, {23.5, 12, 23.5}, {16, 4, 16});  // slab top at y = 16
  const Vec3 a{18.5, 16, 23.5}, b{28.5, 16, 23.5};
  REQUIRE(v.at(23, 20, 23) > 0);
  for (int i = 0; i < 10; ++i) {
    addBlob(v, {a + Vec3{0, double(i) * 0.6, 0}, 7, 1});
    addBlob(v, {b + Vec3{0, double(i) * 0.6, 0}, 7, 1});
  }
  // Between the prongs, above the old top, the solid is continuous.
  CHECK(v.at(18, 20, 23) < 0);
  CHECK(v.at(29, 20, 23) < 0);
  CHECK(v.at(23, 20, 23) < 0);
  CHECK(countComponents(v) == 1);
}

TEST_CASE("local tools move the surface only inside their region of interest", "[level_set]") {
  Volume v = makeSphere({64, 64, 64}, {32, 32, 32}, 20);
  const Volume before = v;
  const BrushParams sp{{52, 32, 32}, 6, 1}, ap{{32, 52, 32}, 6, 1};
  const Edit e = smooth(v, sp);
  const Edit a = addBlob(v, ap);
  CHECK_FALSE(e.empty());
  CHECK_FALSE(a.empty());
  const Box sRoi = boxAround(sp.center, {6, 6, 6}), aRoi = boxAround(ap.center, {6, 6, 6});
  // The edit's region is the ROI grown by the voxels nearer than band + 1 to it (nearer than the
  // band to the cells the tool moved): beyond it nothing changes; between the ROI and it only
  // distances change (they follow the moved surface), never a sign.
  const int reach = int(std::ceil(v.band() + 1)) - 1;
  CHECK(e.region == sRoi.grown(reach).intersect(v.domain()));
  CHECK(a.region == aRoi.grown(reach).intersect(v.domain()));
  int changedOutsideRoi = 0;
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        const Int3 p{x, y, z};
        if (sRoi.contains(p) || aRoi.contains(p)) continue;
        if (!e.region.contains(p) && !a.region.contains(p)) REQUIRE(v.at(p) == before.at(p));
        REQUIRE((v.at(p) < 0) == (before.at(p) < 0));
        changedOutsideRoi += v.at(p) != before.at(p) ? 1 : 0;
      }
  CHECK(changedOutsideRoi > 0);  // the band around the moved surface did follow it
  // One application moves the surface by at most about 1 vu.
  CHECK(v.sample({32, 53, 32}) > -1.2);
  CHECK(v.sample({32, 52.5, 32}) < 0);
}

TEST_CASE("sharpening is smoothing backwards: smoothing rounds an edge off, sharpening does not", "[level_set]") {
  Volume s = makeBox({48, 48, 48}, {23.5, 23.5, 23.5}, {10, 10, 10});  // faces at 13.5 and 33.5
  Volume h = s;
  const Vec3 edge{33.5, 33.5, 23.5};
  const Vec3 probe{33, 33, 23.5};  // 0.5 vu inside both faces near the edge
  const double before = s.sample(probe);
  for (int i = 0; i < 6; ++i) {
    smooth(s, {edge, 6, 1});
    sharpen(h, {edge, 6, 1});
  }
  INFO("before " << before << ", smoothed " << s.sample(probe) << ", sharpened " << h.sample(probe));
  CHECK(s.sample(probe) > before + 0.2);
  CHECK(h.sample(probe) < before + 0.02);
  CHECK(h.sample({23.5, 23.5, 23.5}) < 0);  // and nothing blew up
  CHECK(gradientError(h, {{20, 20, 20}, {30, 30, 30}}).max < 0.05);
}

TEST_CASE("undo data: an edit's old bricks restore the exact previous digest", "[level_set][cow]") {
  Volume v = makeSolid(SolidKind::Torus, {64, 64, 64});
  const std::uint64_t d0 = digest(v);
  const Volume snapshot = v;
  const Edit e = addBlob(v, {{50, 32, 32}, 8, 1});
  const std::uint64_t d1 = digest(v);
  CHECK(d1 != d0);
  CHECK(digest(snapshot) == d0);
  v.publish(e.changes, false);
  CHECK(digest(v) == d0);
  v.publish(e.changes, true);
  CHECK(digest(v) == d1);
}

TEST_CASE("deformative tools refuse bad parameters and leave the volume untouched", "[level_set][errors]") {
  Volume v = makeSphere({48, 48, 48}, {24, 24, 24}, 12);
  const std::uint64_t d0 = digest(v);
  const double nan = std::nan(""), inf = HUGE_VAL;
  const Vec3 ok{36, 24, 24};
  const BrushParams bad[] = {
      {{nan, 24, 24}, 6, 1}, {{36, inf, 24}, 6, 1}, {ok, -6, 1},  {ok, 0, 1},   {ok, nan, 1}, {ok, inf, 1},
      {ok, 6, 0},            {ok, 6, -1},           {ok, 6, 2},   {ok, 6, nan}, {{500, 24, 24}, 6, 1},
      {{-30, 24, 24}, 6, 1}, {ok, 1e9, 1},  {{1e300, 24, 24}, 6, 1}, {{24, -1e300, 24}, 6, 1},
  };
  for (const auto& p : bad) {
    CHECK_THROWS_AS(addBlob(v, p), EngineError);
    CHECK_THROWS_AS(removeBlob(v, p), EngineError);
    CHECK_THROWS_AS(smooth(v, p), EngineError);
    CHECK_THROWS_AS(sharpen(v, p), EngineError);
  }
  for (double k : {nan, inf, -1.0, 0.0, 1000.0}) {
    CHECK_THROWS_AS(dilate(v, k), EngineError);
    CHECK_THROWS_AS(erode(v, k), EngineError);
    CHECK_THROWS_AS(openSolid(v, k), EngineError);
    CHECK_THROWS_AS(closeSolid(v, k), EngineError);
  }
  CHECK_THROWS_AS(meanCurvatureFlow(v, 0), EngineError);
  CHECK_THROWS_AS(meanCurvatureFlow(v, 1, nan), EngineError);
  CHECK_THROWS_AS(meanCurvatureFlow(v, -5), EngineError);
  try {
    addBlob(v, {{500, 24, 24}, 6, 1});
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::OutOfDomain);
    CHECK(e.field() == "center");
  }
  CHECK(digest(v) == d0);
}
