#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>

#include "engine/errors.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/mesh_to_volume.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "mesh_support.hpp"

using namespace marzipan;
using namespace marzipan::test;

TEST_CASE("a sphere mesh imports as its signed distance field", "[mesh]") {
  const Mesh& m = sphereMesh();
  const Volume vol = importMesh(m, {72, 72, 72});
  double worst = 0;
  std::size_t bandVoxels = 0, wrongSign = 0;
  for (int z = 0; z < 72; ++z)
    for (int y = 0; y < 72; ++y)
      for (int x = 0; x < 72; ++x) {
        const double exact = length(Vec3{double(x), double(y), double(z)} - kCentre) - kRadius;
        const float d = vol.at(x, y, z);
        if (std::fabs(exact) > 0.05 && (d < 0) != (exact < 0)) ++wrongSign;
        if (std::fabs(exact) < vol.band() - 0.05) {
          ++bandVoxels;
          worst = std::max(worst, std::fabs(d - exact));
        } else if (std::fabs(exact) > vol.band() + 0.05) {
          REQUIRE(std::fabs(d) == vol.band());
        }
      }
  INFO("max distance error " << worst << " vu over " << bandVoxels << " band voxels");
  CHECK(bandVoxels > 50000);
  CHECK(worst < 0.05);
  CHECK(wrongSign == 0);

  // And the mesh of the imported field is the same sphere again.
  const Mesh again = extractMesh(vol);
  CHECK(eulerCharacteristic(again) == 2);
  CHECK(meshVolume(again) == Approx(meshVolume(m)).epsilon(0.002));
}

TEST_CASE("mesh import is independent of threads, orientation and vertex sharing", "[mesh]") {
  const Mesh m = extractMesh(makeSolid(SolidKind::Torus, {48, 48, 48}));
  ThreadPool pool(3);
  const Volume a = importMesh(m, {48, 48, 48}, 3.0f);
  CHECK(digest(importMesh(m, {48, 48, 48}, 3.0f, pool)) == digest(a));
  CHECK(countComponents(a) == 1);

  Mesh flipped = m;  // inside out: flipped back
  for (std::size_t t = 0; t < flipped.triangleCount(); ++t)
    std::swap(flipped.indices[3 * t + 1], flipped.indices[3 * t + 2]);
  CHECK(digest(importMesh(flipped, {48, 48, 48}, 3.0f)) == digest(a));

  CHECK(digest(importMesh(parseStl(exportStl(m)), {48, 48, 48}, 3.0f)) == digest(a));
}

TEST_CASE("a mesh covering the domain's first voxel fills it", "[mesh]") {
  Mesh cube = parseObj(
      "v -10 -10 -10\nv 40 -10 -10\nv 40 40 -10\nv -10 40 -10\nv -10 -10 40\nv 40 -10 40\nv 40 40 40\nv -10 40 40\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const Volume inside = importMesh(cube, {24, 24, 24});
  CHECK(inside.at(0, 0, 0) == -inside.band());
  CHECK(inside.at(23, 23, 23) == -inside.band());
  CHECK(inside.presentBricks() == 0);

  const Volume placed = importMesh(fitMeshToDomain(cube, {32, 32, 32}, 4), {32, 32, 32});
  CHECK(placed.at(0, 0, 0) == placed.band());
  CHECK(placed.at(4, 16, 16) == Approx(0).margin(1e-5));
  CHECK(placed.at(10, 16, 16) == -placed.band());
  CHECK(insideVolume(placed) == Approx(23.0 * 23 * 23).epsilon(0.01));
}

TEST_CASE("open, non-manifold and empty meshes are refused", "[mesh][errors]") {
  Mesh open = sphereMesh();
  open.indices.resize(open.indices.size() - 3);
  const std::string msg = formatError([&] { importMesh(open, {72, 72, 72}); });
  CHECK(msg.find("not closed: 3 edges") != std::string::npos);

  Mesh doubled = tetrahedron();
  const Mesh t2 = tetrahedron();
  doubled.indices.insert(doubled.indices.end(), t2.indices.begin(), t2.indices.begin() + 3);
  doubled.indices.insert(doubled.indices.end(), {0, 1, 2});
  CHECK(formatError([&] { importMesh(doubled, {16, 16, 16}); }).find("not manifold") != std::string::npos);

  Mesh twisted = tetrahedron();
  std::swap(twisted.indices[1], twisted.indices[2]);
  CHECK(formatError([&] { importMesh(twisted, {16, 16, 16}); }).find("consistently oriented") != std::string::npos);

  CHECK(formatError([&] { importMesh(Mesh{}, {16, 16, 16}); }).find("no triangles") != std::string::npos);
  Mesh bad = tetrahedron();
  bad.indices[4] = 9;
  CHECK(formatError([&] { importMesh(bad, {16, 16, 16}); }).find("out of range") != std::string::npos);
  Mesh nan = tetrahedron();
  nan.positions[5] = std::nanf("");
  CHECK(formatError([&] { importMesh(nan, {16, 16, 16}); }).find("not finite") != std::string::npos);
  CHECK_THROWS_AS(importMesh(tetrahedron(), {4, 16, 16}), EngineError);
}

TEST_CASE("an imported solid that fills the domain's partial edge bricks stores none of them", "[mesh]") {
  // A box from -20 to 14.5 on every axis in a 12^3 domain: every voxel is more than the band
  // inside, so the field is uniformly inside. The bricks at 8..15 are partial (voxels 8..11 in
  // the domain) and lie within reach of the box's faces at 14.5.
  Mesh cube = parseObj(
      "v -20 -20 -20\nv 14.5 -20 -20\nv 14.5 14.5 -20\nv -20 14.5 -20\nv -20 -20 14.5\nv 14.5 -20 14.5\n"
      "v 14.5 14.5 14.5\nv -20 14.5 14.5\n"
      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const Volume v = importMesh(cube, {12, 12, 12});
  CHECK(v.at(11, 11, 11) == -v.band());
  Volume full({12, 12, 12});
  full.fill(true);
  CHECK(v.presentBricks() == 0);
  CHECK(digest(v) == digest(full));
}

namespace {

// A box with a red top (z = hi.z) and a blue bottom, as 8 vertices of those colours: the sides
// shade from blue to red, linearly in z on both of their triangles.
Mesh twoColoredBox(Vec3 lo, Vec3 hi) {
  Mesh m;
  for (int c = 0; c < 8; ++c) {
    m.positions.insert(m.positions.end(), {float(c & 1 ? hi.x : lo.x), float(c & 2 ? hi.y : lo.y), float(c & 4 ? hi.z : lo.z)});
    m.colors.insert(m.colors.end(), {std::uint8_t(c & 4 ? 255 : 0), 0, std::uint8_t(c & 4 ? 0 : 255)});
  }
  m.indices = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return m;
}

}  // namespace

TEST_CASE("an imported mesh's vertex colours colour the band by the nearest surface point", "[mesh][color]") {
  const Vec3 lo{10.5, 11.25, 9.75}, hi{40.25, 38.5, 41.5};
  const Mesh box = twoColoredBox(lo, hi);
  REQUIRE(meshVolume(box) > 0);
  ThreadPool pool(2);
  const Volume vol = importMesh(box, {52, 52, 52}, Volume::kDefaultBand, pool);
  REQUIRE(vol.paintedBricks() > 0);
  CHECK(vol.baseColor() == kClayColor);
  // The exact colour at a surface point of height z, before rounding.
  auto redAt = [&](double z) { return 255 * std::clamp((z - lo.z) / (hi.z - lo.z), 0.0, 1.0); };
  std::size_t band = 0, top = 0, bottom = 0, wrong = 0, ties = 0;
  for (int z = 0; z < 52; ++z)
    for (int y = 0; y < 52; ++y)
      for (int x = 0; x < 52; ++x) {
        const Vec3 p{double(x), double(y), double(z)};
        const Texel t = vol.texel({x, y, z});
        if (!(std::fabs(vol.at(x, y, z)) < vol.band())) {
          wrong += t == texelOf(kClayColor) ? 0 : 1;
          continue;
        }
        ++band;
        // The nearest surface point: the clamped point outside; inside, the point on the
        // nearest face (voxels as near to two faces as each other are left out).
        Vec3 foot{std::clamp(p.x, lo.x, hi.x), std::clamp(p.y, lo.y, hi.y), std::clamp(p.z, lo.z, hi.z)};
        if (foot == p) {
          double best = 1e9, second = 1e9;
          for (int a = 0; a < 3; ++a)
            for (const double face : {lo[a], hi[a]}) {
              const double d = std::fabs(p[a] - face);
              if (d < best) {
                second = best, best = d;
                foot = p, foot[a] = face;
              } else if (d < second) {
                second = d;
              }
            }
          if (second - best < 1e-9) {
            ++ties;
            continue;
          }
        }
        const double red = redAt(foot.z);
        top += red == 255 ? 1 : 0, bottom += red == 0 ? 1 : 0;
        const bool exact = red == 0 || red == 255;  // a face of one colour, whatever the weights
        const bool ok = t.g == 0 && t.mask == 0 && t.r + t.b == 255 &&
                        (exact ? t.r == red : std::fabs(t.r - red) <= 0.5 + 1e-6);
        wrong += ok ? 0 : 1;
      }
  INFO(band << " band voxels, " << top << " nearest to the red top, " << bottom << " to the blue bottom, " << ties
            << " ties left out");
  CHECK(top > 2000);
  CHECK(bottom > 2000);
  CHECK(wrong == 0);
  // The same volume on one thread, and without colours no channel at all.
  CHECK(importMesh(box, {52, 52, 52}).paintedBricks() == vol.paintedBricks());
  Mesh plain = box;
  plain.colors.clear();
  CHECK(importMesh(plain, {52, 52, 52}).paintedBricks() == 0);
  Mesh bad = box;
  bad.colors.pop_back();
  CHECK(formatError([&] { importMesh(bad, {52, 52, 52}); }).find("colours must be one per vertex") != std::string::npos);
}

// A sphere painted red over its upper half by the paint tool, written as .ply, .obj and .glb and read
// back: how many band voxels of the read volume hold, within 8 on each channel, the colour the
// painted volume holds there. Those that do not all lie in the dab's soft border: at 0.95 to 1
// of its radius from the pole, heights 0 to 1.95 vu above the centre on the surface, where the
// colour changes by up to 140 a vu and a foot point found another way (central differences
// when painting, the nearest triangle when reading) lands on another shade.
TEST_CASE("a half-painted sphere keeps its halves' colours through .ply, .obj and .glb", "[mesh][color]") {
  const Int3 dims{64, 64, 64};
  const Vec3 centre{31.6, 32.3, 31.9};
  Volume vol = makeSphere(dims, centre, 20);
  PaintSettings st;
  st.color = {230, 20, 30};
  st.radius = 20 * std::sqrt(2.0);  // the dab at the top pole reaches the equator
  st.hardness = 0.95;
  paint(vol, st, centre + Vec3{0, 0, 20});
  REQUIRE(vol.paintedBricks() > 0);
  const Mesh m = extractMesh(vol);
  for (const MeshFormat f : {MeshFormat::Ply, MeshFormat::Obj, MeshFormat::Glb}) {
    const Volume back = importMesh(parseMesh(exportMesh(m, f), f), dims);
    std::size_t band = 0, close = 0, red = 0, redBack = 0, farFromBorder = 0;
    for (int z = 0; z < dims.z; ++z)
      for (int y = 0; y < dims.y; ++y)
        for (int x = 0; x < dims.x; ++x) {
          if (!(std::fabs(back.at(x, y, z)) < back.band())) continue;
          ++band;
          const Texel a = vol.texel({x, y, z}), b = back.texel({x, y, z});
          const bool ok = std::abs(a.r - b.r) <= 8 && std::abs(a.g - b.g) <= 8 && std::abs(a.b - b.b) <= 8;
          close += ok ? 1 : 0;
          farFromBorder += !ok && (z - centre.z < -0.5 || z - centre.z > 2.5) ? 1 : 0;
          red += a.color() == st.color ? 1 : 0;
          redBack += b.color() == st.color ? 1 : 0;
        }
    const double share = double(close) / double(band);
    INFO((f == MeshFormat::Ply ? ".ply" : f == MeshFormat::Obj ? ".obj" : ".glb") << ": " << close << " of " << band << " band voxels within 8 ("
                                                   << share << "), " << red << " red painted, " << redBack << " red read");
    CHECK(red > band / 3);
    CHECK(share > 0.99);
    CHECK(farFromBorder == 0);
  }
}
