// Splats: foot points against analytic spheres and a brute-force reference, per-brick
// re-extraction after edits, the texels of painted bricks, the codec's two versions byte for
// byte, and the decoder against truncated and corrupted buffers.
// Conventions as in engine/splats.hpp.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/paint.hpp"
#include "engine/simd_width.hpp"
#include "engine/solids.hpp"
#include "engine/splats.hpp"
#include "engine/stencil.hpp"
#include "protocol/cpp/splat_width.hpp"
#include "protocol/cpp/splats.hpp"
#include "support.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

namespace {

double degreesBetween(Vec3 a, Vec3 b) {
  const double c = std::clamp(dot(normalized(a), normalized(b)), -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

// Lets the splat encoder take its AVX2 form again when it goes out of scope (splat_width.hpp),
// also when the test that limited it fails.
struct SplatAvx2AtExit {
  SplatAvx2AtExit() = default;
  SplatAvx2AtExit(const SplatAvx2AtExit&) = delete;
  SplatAvx2AtExit& operator=(const SplatAvx2AtExit&) = delete;
  ~SplatAvx2AtExit() { splat_width::allowAvx2(true); }
};

Vec3 position(const Splat& s) { return {s.x, s.y, s.z}; }
Vec3 normal(const Splat& s) { return {s.nx, s.ny, s.nz}; }

struct Key {
  int x, y, z;
  friend bool operator<(const Key& a, const Key& b) { return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x); }
  friend bool operator==(const Key&, const Key&) = default;
};
Key key(Int3 b) { return {b.x, b.y, b.z}; }

using SplatMap = std::map<Key, std::vector<Splat>>;

SplatMap toMap(const std::vector<BrickSplats>& all) {
  SplatMap m;
  for (const auto& b : all)
    if (!b.points.empty()) m[key(b.brick)] = b.points;
  return m;
}

// fn(p, d, brick) for every surface voxel p of v (splats.hpp: |d| < kSurfaceNear, or a face
// neighbour of the other sign), in index order, d its value.
template <class F>
void forEachSurfaceVoxel(const Volume& v, F&& fn) {
  const Int3 n = v.dims();
  const Int3 six[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        const Int3 p{x, y, z};
        const float d = v.at(p);
        bool surface = std::fabs(d) < kSurfaceNear;
        for (const Int3& s : six) surface = surface || ((v.at(p + s) < 0) != (d < 0));
        if (surface) fn(p, d, Int3{x / 8, y / 8, z / 8});
      }
}

// The definition of splats.hpp evaluated voxel by voxel through Volume::at, in double.
SplatMap referenceSplats(const Volume& v) {
  SplatMap m;
  forEachSurfaceVoxel(v, [&](Int3 p, double d, Int3 b) {
        const int x = p.x, y = p.y, z = p.z;
        const Vec3 g = v.voxelGradient(p);
        Splat s{float(x), float(y), float(z), 0, 0, 1};
        if (length(g) > 0) {
          const Vec3 nn = normalized(g);
          Vec3 q = Vec3{double(x), double(y), double(z)} - d * nn;
          for (int a = 0; a < 3; ++a) q[a] = std::clamp(q[a], 8.0 * b[a] - 2, 8.0 * b[a] + 10 - 12.0 / 16384);
          s = {float(q.x), float(q.y), float(q.z), float(nn.x), float(nn.y), float(nn.z)};
        }
        m[key(b)].push_back(s);
      });
  return m;
}

void requireSameWithin(const SplatMap& got, const SplatMap& want, double posTol, double dirTol) {
  REQUIRE(got.size() == want.size());
  for (const auto& [k, pts] : want) {
    INFO("brick " << k.x << "," << k.y << "," << k.z);
    const auto it = got.find(k);
    REQUIRE(it != got.end());
    REQUIRE(it->second.size() == pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      REQUIRE(length(position(it->second[i]) - position(pts[i])) < posTol);
      REQUIRE(length(normal(it->second[i]) - normal(pts[i])) < dirTol);
    }
  }
}

struct SphereError {
  double position = 0, degrees = 0;
  std::size_t points = 0;
};

SphereError sphereError(const std::vector<BrickSplats>& bricks, Vec3 c, double r) {
  SphereError e;
  for (const auto& b : bricks)
    for (const Splat& s : b.points) {
      const Vec3 q = position(s);
      e.position = std::max(e.position, std::fabs(length(q - c) - r));
      e.degrees = std::max(e.degrees, degreesBetween(normal(s), q - c));
      ++e.points;
    }
  return e;
}

bool rejectedAsFormat(std::span<const std::uint8_t> bytes) {
  try {
    decodeSplats(bytes);
  } catch (const EngineError& e) {
    return e.kind() == ErrorKind::Format;
  }
  return false;
}

}  // namespace

TEST_CASE("decoded splats of spheres lie on the surface with the analytic normal", "[splats]") {
  struct Case {
    Int3 dims;
    Vec3 center;
    double radius;
  };
  for (const Case& k :
       {Case{{72, 72, 72}, {35.3, 36.7, 35.9}, 30.0}, Case{{256, 256, 256}, {127.6, 128.2, 127.9}, 100.0}}) {
    const Volume v = makeSphere(k.dims, k.center, k.radius);
    const auto bricks = extractAllSplats(v);
    const auto bytes = encodeSplats(bricks);
    const auto decoded = decodeSplats(bytes);
    const SphereError raw = sphereError(bricks, k.center, k.radius);
    const SphereError e = sphereError(decoded, k.center, k.radius);
    INFO("radius " << k.radius << ": " << e.points << " points, max foot-point error " << e.position
                   << " vu (before quantization " << raw.position << "), max normal error " << e.degrees << " deg, "
                   << double(bytes.size()) / double(e.points) << " bytes per point");
    CHECK(e.points == raw.points);
    // A sphere has about 4 pi r^2 * 1.33 voxels next to its surface.
    CHECK(double(e.points) > 4 * std::numbers::pi * k.radius * k.radius);
    CHECK(double(e.points) < 8 * std::numbers::pi * k.radius * k.radius);
    CHECK(e.position < 0.01);
    CHECK(e.degrees < 1.0);
    CHECK(double(bytes.size()) / double(e.points) < 8.5);
  }
}

TEST_CASE("every voxel next to the surface yields exactly one splat", "[splats]") {
  SECTION("pig in a domain whose sides are not multiples of 8") {
    const Volume v = makeSolid(SolidKind::Pig, {70, 61, 53});
    requireSameWithin(toMap(extractAllSplats(v)), referenceSplats(v), 1e-4, 1e-5);
  }
  SECTION("a box cut by the domain's edges: uniform inside bricks against the air outside") {
    const Volume v = makeBox({44, 40, 37}, {30, 20, 18}, {25, 30, 10});
    const SplatMap want = referenceSplats(v);
    CHECK(want.size() > 20);
    requireSameWithin(toMap(extractAllSplats(v)), want, 1e-4, 1e-5);
  }
  SECTION("bricks of -band next to bricks of +band") {
    Volume v({48, 48, 48});
    const Box cube{{8, 16, 8}, {32, 32, 24}};
    std::vector<float> inside(std::size_t(cube.voxels()), -v.band());
    v.scatter(cube, inside.data(), cube);
    CHECK(v.presentBricks() == 0);
    const SplatMap want = referenceSplats(v);
    CHECK(!want.empty());
    requireSameWithin(toMap(extractAllSplats(v)), want, 1e-4, 1e-5);
  }
  SECTION("torus") {
    const Volume v = makeSolid(SolidKind::Torus, {64, 64, 64});
    requireSameWithin(toMap(extractAllSplats(v)), referenceSplats(v), 1e-4, 1e-5);
  }
}

// The definition of splats.hpp evaluated in float through Volume::at, with the operations of
// the extraction in their order (a float central difference, 1/sqrt of the squared length, the
// foot point clamped to the brick's encodable range): what the extraction must give bit for bit.
SplatMap exactSplats(const Volume& v) {
  SplatMap m;
  forEachSurfaceVoxel(v, [&](Int3 p, float d, Int3 b) {
        const int x = p.x, y = p.y, z = p.z;
        const GradStencil st = GradStencil::around(p, [&](Int3 q) { return v.at(q); });
        const float gx = st.difference(0), gy = st.difference(1), gz = st.difference(2);
        const float len2 = gx * gx + gy * gy + gz * gz;
        Splat s{float(x), float(y), float(z), 0, 0, 1};
        if (len2 > 0) {
          const float inv = 1 / std::sqrt(len2);
          s.nx = gx * inv, s.ny = gy * inv, s.nz = gz * inv;
          auto foot = [&](float c, float nc, int brick) {
            const float o = float(8 * brick);
            return std::clamp(c - d * nc, o + kSplatPositionLow, o + kSplatPositionLow + kSplatPositionStep * float(kSplatPositionMax));
          };
          s.x = foot(float(x), s.nx, b.x), s.y = foot(float(y), s.ny, b.y), s.z = foot(float(z), s.nz, b.z);
        }
        m[key(b)].push_back(s);
      });
  return m;
}

TEST_CASE("splats are bit for bit the definition evaluated in float", "[splats]") {
  // Partial bricks at the far faces, uniform bricks against the domain's edge and against
  // each other, stored bricks next to uniform ones on both sides, and an edited surface whose
  // bricks are re-extracted one by one (the delta path).
  SECTION("pig in a domain whose sides are not multiples of 8") {
    const Volume v = makeSolid(SolidKind::Pig, {70, 61, 53});
    CHECK(toMap(extractAllSplats(v)) == exactSplats(v));
  }
  SECTION("a box cut by the domain's edges") {
    const Volume v = makeBox({44, 40, 37}, {30, 20, 18}, {25, 30, 10});
    CHECK(toMap(extractAllSplats(v)) == exactSplats(v));
  }
  SECTION("bricks of -band next to bricks of +band") {
    Volume v({48, 48, 48});
    const Box cube{{8, 16, 8}, {32, 32, 24}};
    std::vector<float> inside(std::size_t(cube.voxels()), -v.band());
    v.scatter(cube, inside.data(), cube);
    CHECK(toMap(extractAllSplats(v)) == exactSplats(v));
  }
  SECTION("a sphere after blobs, brick by brick") {
    Volume v = makeSphere({64, 64, 64}, {31.5, 32.2, 30.8}, 20);
    addBlob(v, BrushParams{{51.5, 32.2, 30.8}, 7.0, 1.0});
    removeBlob(v, BrushParams{{31.5, 12.2, 30.8}, 6.0, 1.0});
    const SplatMap want = exactSplats(v);
    SplatMap got;
    for (int z = 0; z < v.brickDims().z; ++z)
      for (int y = 0; y < v.brickDims().y; ++y)
        for (int x = 0; x < v.brickDims().x; ++x) {
          const BrickSplats b = extractBrickSplats(v, {x, y, z});
          if (!b.points.empty()) got[key(b.brick)] = b.points;
        }
    CHECK(got.size() > 100);
    CHECK(got == want);
  }
}

TEST_CASE("splats and the bricks around a change are the same at both vector widths", "[splats]") {
  // A sphere cut by the domain's far faces, a block of it overwritten with the values on the
  // edges of the slice tests (signed zeros, +-kSurfaceNear and the floats next to them,
  // subnormals), then a blob over both.
  if (!test::avx2OrSkipped()) return;
  const test::WidestWidthAtExit restore;
  Volume v = makeSphere({61, 53, 47}, {38.3, 31.1, 28.4}, 20);
  const float n = kSurfaceNear, tiny = std::numeric_limits<float>::denorm_min();
  const float edges[] = {0.0f, -0.0f, n, -n, std::nextafter(n, 0.0f), -std::nextafter(n, 0.0f),
                         std::nextafter(n, 2.0f), tiny, -tiny, -1.5f, 2.5f};
  const Box block{{36, 12, 20}, {52, 28, 36}};
  std::vector<float> values(std::size_t(block.voxels()));
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = edges[(i * 7 + i / 13) % std::size(edges)];
  v.scatter(block, values.data(), block);
  const Volume was = v;
  const Edit e = addBlob(v, BrushParams{{44, 20, 28}, 9.0, 1.0});
  REQUIRE(!e.empty());
  auto atWidth = [&](simd_width::Width w) {
    simd_width::limitWidth(w);
    return std::make_tuple(toMap(extractAllSplats(was)), toMap(extractAllSplats(v)), bricksAroundChanges(v, e.changes));
  };
  const auto sse2 = atWidth(simd_width::Width::Sse2);
  const auto widest = atWidth(simd_width::Width::Widest);
  CHECK(std::get<0>(sse2) == exactSplats(was));
  CHECK(std::get<1>(sse2) == exactSplats(v));
  CHECK(std::get<2>(sse2).size() > 4);
  CHECK(widest == sse2);
}

TEST_CASE("splats do not depend on the thread count", "[splats]") {
  const Volume v = makeSolid(SolidKind::Pig, {96, 96, 96});
  ThreadPool pool(3);
  CHECK(extractAllSplats(v, pool) == extractAllSplats(v));
}

TEST_CASE("re-extracting the bricks around an edit matches a fresh extraction", "[splats]") {
  Volume v = makeSphere({64, 64, 64}, {31.5, 32.2, 30.8}, 20);
  ThreadPool pool(2);
  SplatMap shown = toMap(extractAllSplats(v, pool));
  const Vec3 spots[] = {{51.5, 32.2, 30.8}, {31.5, 12.2, 30.8}, {45.6, 46.3, 30.8}, {31.5, 32.2, 50.8}};
  int round = 0;
  for (const Vec3& c : spots) {
    for (int k = 0; k < 3; ++k) {
      const BrushParams brush{c, 7.0, 1.0};
      const Edit e = (round++ % 2 == 0) ? addBlob(v, brush, pool) : removeBlob(v, brush, pool);
      REQUIRE(!e.empty());
      const auto around = bricksAroundChanges(v, e.changes);
      CHECK(!around.empty());
      // The delta goes through the wire format: empty blocks clear bricks that lost their points.
      const auto delta = decodeSplats(encodeSplats(extractSplats(v, around, pool)));
      REQUIRE(delta.size() == around.size());
      const auto exact = extractSplats(v, around);
      for (const auto& b : exact) {
        if (b.points.empty()) {
          shown.erase(key(b.brick));
        } else {
          shown[key(b.brick)] = b.points;
        }
      }
      REQUIRE(shown == toMap(extractAllSplats(v)));
      for (std::size_t i = 0; i < delta.size(); ++i) {
        REQUIRE(delta[i].brick == exact[i].brick);
        REQUIRE(delta[i].points.size() == exact[i].points.size());
      }
    }
  }
}

TEST_CASE("the bricks around a change are those with a changed value next to a surface voxel", "[splats]") {
  const Volume v = makeSphere({64, 64, 64}, {31.5, 32.2, 30.8}, 20);
  // A stored brick well inside the grid (the sphere's surface crosses it, near x = 51.5).
  const Int3 b = Bricks::brickOf(Int3{51, 32, 30});
  const Int3 o = Bricks::origin(b);
  const BrickRef before = v.brick(b);
  REQUIRE(before.data);
  auto changedAt = [&](Int3 local) {
    auto data = std::make_shared<Brick>(*before.data);
    data->v[Bricks::index(local)] += 0.25f;
    return std::vector<BrickChange>{{b, before, BrickRef{data, false}}};
  };
  // A voxel of the low y face next to the surface, and its neighbour across the face too: this
  // brick and that neighbour, in z, y, x order.
  REQUIRE(std::fabs(v.at(o + Int3{3, 0, 5})) < kSurfaceNear);
  REQUIRE(std::fabs(v.at(o + Int3{3, -1, 5})) < kSurfaceNear);
  CHECK(bricksAroundChanges(v, changedAt({3, 0, 5})) == std::vector<Int3>{b - Int3{0, 1, 0}, b});
  // A voxel of the high x face 3.9 vu outside, no neighbour of it near the surface: none.
  REQUIRE(v.at(o + Int3{7, 4, 5}) > 3 * kSurfaceNear);
  CHECK(bricksAroundChanges(v, changedAt({7, 4, 5})).empty());
  // The same voxels, its channels a new buffer: the brick (its texels), not the neighbours.
  const BrickRef repainted{before.data, false, std::make_shared<BrickPaint>()};
  CHECK(bricksAroundChanges(v, {{b, before, repainted}}) == std::vector<Int3>{b});
  // A uniform brick turning to the other side puts the surface on its faces and its neighbours'.
  const Int3 inside = Bricks::brickOf(Int3{32, 32, 30});
  REQUIRE(!v.brick(inside).data);
  REQUIRE(v.brick(inside).inside);
  CHECK(bricksAroundChanges(v, {{inside, v.brick(inside), BrickRef{nullptr, false}}}).size() == 7);
}

namespace {

// Checks bricksAroundChanges against extraction in the two states `was` and `now` (now = was
// with `changes`): every brick of `check` whose block differs between them is listed; the list
// is sorted z, y, x without duplicates, and the same with the volume in either state and with
// the changes reversed (an undo). Returns the list.
std::vector<Int3> checkAround(const Volume& was, const Volume& now, const std::vector<BrickChange>& changes,
                const std::vector<Int3>& check) {
  auto zyx = [](Int3 a, Int3 b) { return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x); };
  const std::vector<Int3> listed = bricksAroundChanges(now, changes);
  REQUIRE(std::is_sorted(listed.begin(), listed.end(), zyx));
  REQUIRE(std::adjacent_find(listed.begin(), listed.end()) == listed.end());
  CHECK(bricksAroundChanges(was, changes) == listed);
  std::vector<BrickChange> undo;
  for (const BrickChange& c : changes) undo.push_back({c.brick, c.after, c.before});
  CHECK(bricksAroundChanges(was, undo) == listed);
  CHECK(bricksAroundChanges(now, undo) == listed);
  for (const Int3 b : check) {
    if (extractBrickSplats(was, b) != extractBrickSplats(now, b)) {
      INFO("brick " << b.x << "," << b.y << "," << b.z << " changed its splats");
      REQUIRE(std::binary_search(listed.begin(), listed.end(), b, zyx));
    }
  }
  return listed;
}

}  // namespace

TEST_CASE("the bricks around a list naming a brick twice are the changed bricks and all their face neighbours", "[splats]") {
  const Volume v({20, 20, 20});  // 3 x 3 x 3 bricks, the last cut by the domain's edge
  const auto change = [&](Int3 b) { return BrickChange{b, v.brick(b), v.brick(b)}; };
  const std::vector<BrickChange> changes = {change({2, 1, 1}), change({0, 0, 0}), change({0, 0, 0})};
  const std::vector<Int3> want = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 1, 0}, {0, 0, 1}, {2, 0, 1},
                                  {1, 1, 1}, {2, 1, 1}, {2, 2, 1}, {2, 1, 2}};
  CHECK(bricksAroundChanges(v, changes) == want);
}

TEST_CASE("the bricks around a one-voxel change list every brick whose splats change, for every voxel", "[splats]") {
  const Volume v = makeSphere({64, 64, 64}, {31.5, 32.2, 30.8}, 20);
  // A stored brick becoming another stored brick, and a uniform outside brick becoming stored.
  const Int3 stored = Bricks::brickOf(Int3{51, 32, 30});
  const Int3 air{1, 1, 1};
  REQUIRE(v.brick(stored).data);
  REQUIRE(!v.brick(air).data);
  REQUIRE(!v.brick(air).inside);
  int checked = 0, leftOut = 0;
  for (const Int3 b : {stored, air}) {
    const BrickRef before = v.brick(b);
    Brick base;
    if (before.data) {
      base = *before.data;
    } else {
      std::fill(std::begin(base.v), std::end(base.v), v.band());
    }
    // The brick and its face neighbours: no other brick reads its voxels.
    std::vector<Int3> around{b};
    for (int a = 0; a < 3; ++a)
      for (int s = -1; s <= 1; s += 2) {
        Int3 nb = b;
        nb[a] += s;
        around.push_back(nb);
      }
    for (int i = 0; i < kBrickVoxels; ++i, ++checked) {
      auto data = std::make_shared<Brick>(base);
      data->v[i] = data->v[i] > 0 ? data->v[i] - 0.5f : data->v[i] + 0.5f;
      const Int3 l = Bricks::local(i);
      INFO("brick " << b.x << "," << b.y << "," << b.z << " voxel " << l.x << "," << l.y << "," << l.z);
      const std::vector<BrickChange> changes{{b, before, BrickRef{data, false}}};
      Volume now = v;
      now.publish(changes, true);
      leftOut += int(around.size() - checkAround(v, now, changes, around).size());
    }
  }
  CHECK(checked == 2 * kBrickVoxels);
  // Most voxels of the two bricks are away from the surface (air: all of them, 0.5 off band).
  CHECK(leftOut > 7 * kBrickVoxels);
}

TEST_CASE("the bricks around random edits list every brick whose splats change, in both directions", "[splats]") {
  // A domain of no multiple of 8 (bricks cut by its far edge), a sphere cut by its far z face,
  // painted over part of it.
  const Vec3 c{38.3, 31.1, 28.4};
  Volume v = makeSphere({61, 53, 47}, c, 20);
  PaintSettings red;
  red.color = {200, 20, 10};
  red.radius = 14;
  paint(v, red, {45, 27, 26});
  std::vector<Int3> all;
  const Int3 n = v.brickDims();
  for (int z = 0; z < n.z; ++z)
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) all.push_back({x, y, z});
  std::mt19937 rng{32};
  std::uniform_real_distribution<double> unit(-1, 1);
  int edits = 0, changedBricks = 0, changedLeftOut = 0;
  for (int round = 0; round < 48; ++round) {
    Vec3 dir{unit(rng), unit(rng), unit(rng)};
    // Every third edit towards the far edges (the cut bricks).
    if (round % 3 == 2) dir = {std::fabs(dir.x), std::fabs(dir.y), std::fabs(dir.z)};
    dir = normalized(dir);
    // On the surface, within the domain.
    Vec3 at = c + dir * 20;
    at = {std::min(at.x, 59.5), std::min(at.y, 51.5), std::min(at.z, 45.5)};
    const BrushParams brush{at, 3 + 3 * std::fabs(unit(rng)), 1};
    const Volume was = v;
    Edit e;
    switch (round % 5) {
      case 0: e = addBlob(v, brush); break;
      case 1: e = removeBlob(v, brush); break;
      case 2: e = smooth(v, brush); break;
      case 3: {
        PaintSettings blue;
        blue.color = {10, 30, 220};
        blue.radius = brush.radius;
        e = paint(v, blue, at);
        break;
      }
      default: {
        const StrokeDab dabs[] = {StrokeDab(at), StrokeDab(at + Vec3{2, 1, 0}), StrokeDab(at + Vec3{4, 1, 1})};
        e = applyStroke(v, StrokeSettings(Brush::AddBlob, brush.radius, 1), dabs, {});
      }
    }
    if (e.empty()) continue;
    ++edits;
    changedBricks += int(e.changes.size());
    INFO("round " << round);
    const std::vector<Int3> listed = checkAround(was, v, e.changes, all);
    for (const BrickChange& ch : e.changes) changedLeftOut += !std::count(listed.begin(), listed.end(), ch.brick);
  }
  CHECK(edits > 40);
  // Changed bricks whose splats came out the same: a tenth at least (the changes of a dab
  // reach past the surface, into the band).
  CHECK(changedLeftOut * 10 > changedBricks);
}

TEST_CASE("splat encoding: exact layout and quantization error", "[splats]") {
  const Volume v = makeSolid(SolidKind::Dumbbell, {64, 48, 48});
  auto bricks = extractAllSplats(v);
  bricks.push_back({v.brickDims() - Int3{1, 1, 1}, {}});  // an empty block
  std::size_t points = 0;
  for (const auto& b : bricks) points += b.points.size();
  const auto bytes = encodeSplats(bricks);
  CHECK(bytes.size() == 16 + 8 * bricks.size() + 8 * points);
  CHECK(bytes.size() == encodedSplatsSize(bricks));
  CHECK(std::string(bytes.begin(), bytes.begin() + 4) == "MZSP");
  const auto back = decodeSplats(bytes);
  REQUIRE(back.size() == bricks.size());
  double worstPos = 0, worstDeg = 0;
  for (std::size_t i = 0; i < back.size(); ++i) {
    REQUIRE(back[i].brick == bricks[i].brick);
    REQUIRE(back[i].points.size() == bricks[i].points.size());
    for (std::size_t k = 0; k < back[i].points.size(); ++k) {
      const Splat &a = back[i].points[k], &b = bricks[i].points[k];
      worstPos = std::max(
          {worstPos, double(std::fabs(a.x - b.x)), double(std::fabs(a.y - b.y)), double(std::fabs(a.z - b.z))});
      worstDeg = std::max(worstDeg, degreesBetween(normal(a), normal(b)));
    }
  }
  INFO("worst position error " << worstPos << " vu per axis, worst normal error " << worstDeg << " deg");
  CHECK(worstPos <= 3.0 / 8192 + 1e-5);
  CHECK(worstDeg < 0.15);
  // Quantization is idempotent: re-encoding decoded points gives the same points back (on the
  // octahedron's folded seam two codes may name one normal, so compare points, not bytes).
  CHECK(decodeSplats(encodeSplats(back)) == back);
}

TEST_CASE("splat points encoded four or eight at a time are the bytes of each encoded alone", "[splats]") {
  const SplatAvx2AtExit restore;
  // A block of one point takes the one-point encoder; a block of 512 points the four-at-a-time
  // one where the build has it, or the eight-at-a-time one where the CPU has AVX2 (each width in
  // turn; a group one refuses, for a subnormal normal, leaves the rest of the block to the
  // narrower ones). Points of every kind: clamped positions, normals of any length and of the
  // lower half, zero and signed-zero components, subnormal normals, huge values.
  std::mt19937 rng(32);
  std::uniform_real_distribution<float> pos(-3.0f, 11.0f), dir(-1.5f, 1.5f);  // around brick (3, 1, 0)
  std::vector<Splat> points;
  const float tiny = 1e-40f, huge = 3e38f;
  const std::vector<Splat> special = {
      {0, 0, 0, 0, 0, 0},        {-0.0f, 8, 10, -0.0f, -0.0f, -0.0f}, {-2, -2, -2, 0, 0, -1},
      {9.999f, 10, 30, 1, 0, 0}, {huge, -huge, 1, huge, huge, -huge},  {1, 2, 3, tiny, 0, -tiny},
      {1, 2, 3, tiny, tiny, tiny}, {1, 2, 3, 0, tiny, 0},             {4, 4, 4, -0.5f, 0.5f, -0.0f},
      {4, 4, 4, 0, -1, -1e-30f}, {4, 4, 4, 1e-30f, 0, 0},              {4, 4, 4, -0.25f, -0.75f, -0.0f}};
  for (int round = 0; round < 3; ++round) points.insert(points.end(), special.begin(), special.end());
  for (int i = 0; i < 4000; ++i) {
    Splat s{24 + pos(rng), 8 + pos(rng), pos(rng), dir(rng), dir(rng), dir(rng)};
    if (i % 7 == 0) s.nz = 0;
    if (i % 11 == 0) s.nx = -0.0f;
    points.push_back(s);
  }
  std::shuffle(points.begin() + std::ptrdiff_t(special.size()), points.end(), rng);
  for (const bool avx2 : {false, true}) {
    splat_width::allowAvx2(avx2);
    for (const bool painted : {false, true}) {
      INFO((painted ? "painted" : "unpainted") << (avx2 ? ", AVX2 allowed" : ", SSE2"));
      const std::size_t pointBytes = painted ? kSplatPaintedPointBytes : kSplatPointBytes;
      for (std::size_t at = 0; at + 512 <= points.size(); at += 500) {
        BrickSplats block{{3, 1, 0}, std::vector<Splat>(points.begin() + std::ptrdiff_t(at),
                                                        points.begin() + std::ptrdiff_t(at + 512)), {}};
        if (painted)
          for (std::size_t i = 0; i < block.points.size(); ++i)
            block.texels.push_back({std::uint8_t(i), std::uint8_t(3 * i), std::uint8_t(7 * i), std::uint8_t(255 - i)});
        std::vector<std::uint8_t> all, one;
        encodeSplatBlock(block, all);
        REQUIRE(all.size() == kSplatBrickHeaderBytes + pointBytes * 512);
        for (std::size_t i = 0; i < block.points.size(); ++i) {
          BrickSplats alone{block.brick, {block.points[i]}, {}};
          if (painted) alone.texels = {block.texels[i]};
          encodeSplatBlock(alone, one);
          INFO("point " << at + i);
          REQUIRE(std::equal(one.begin() + kSplatBrickHeaderBytes, one.end(),
                             all.begin() + std::ptrdiff_t(kSplatBrickHeaderBytes + pointBytes * i)));
        }
      }
    }
  }
  splat_width::allowAvx2(true);
  // Normals so short that 1 / l1 overflows keep their direction (protocol/cpp/splats.cpp,
  // kTinyNormalScale): unscaled, a zero component made a NaN, whose conversion to an integer was
  // undefined (clang's UBSan stopped here), and (0, 1e-40, 0) came back as (-0, 0, -1).
  for (const Splat& s : {Splat{1, 2, 3, 0, tiny, 0}, Splat{1, 2, 3, tiny, 0, -tiny}, Splat{1, 2, 3, -tiny, tiny, tiny}}) {
    const std::vector<BrickSplats> back = decodeSplats(encodeSplats({BrickSplats{{0, 0, 0}, {s}, {}}}));
    REQUIRE(back.size() == 1);
    REQUIRE(back[0].points.size() == 1);
    const Vec3 n = normal(back[0].points[0]), expected{s.nx * 1e30, s.ny * 1e30, s.nz * 1e30};
    INFO("decoded normal " << n.x << " " << n.y << " " << n.z);
    CHECK(degreesBetween(n, expected) < 0.2);
  }
  // Non-finite values are refused wherever they sit among the points, in every field, at each
  // width: with an odd count (511: 3066 floats) the last point's ny and nz lie past the last
  // whole group of four (or eight) floats, which the check takes one by one; with 510 (3060
  // floats) the last four lie past the last group of eight, which the four-wide check takes.
  for (const bool avx2 : {false, true}) {
    splat_width::allowAvx2(avx2);
    for (const std::size_t count : {512, 511, 510})
      for (const std::size_t i : {std::size_t(0), std::size_t(1), std::size_t(5), count - 2, count - 1})
        for (int field = 0; field < 6; ++field) {
          BrickSplats bad{{0, 0, 0}, std::vector<Splat>(points.begin(), points.begin() + std::ptrdiff_t(count)), {}};
          constexpr float Splat::*kFields[6] = {&Splat::x, &Splat::y, &Splat::z, &Splat::nx, &Splat::ny, &Splat::nz};
          bad.points[i].*kFields[field] = field % 2 ? std::numeric_limits<float>::infinity() : std::nanf("");
          std::vector<std::uint8_t> out;
          INFO(count << " points, point " << i << ", field " << field << (avx2 ? ", AVX2 allowed" : ", SSE2"));
          CHECK_THROWS_AS(encodeSplatBlock(bad, out), EngineError);
        }
  }
}

TEST_CASE("splat blocks joined into a buffer are encodeSplats' bytes, in the order given", "[splats]") {
  const Volume v = makeSolid(SolidKind::Dumbbell, {64, 48, 48});
  auto bricks = extractAllSplats(v);
  REQUIRE(bricks.size() > 10);
  bricks.push_back({v.brickDims() - Int3{1, 1, 1}, {}});  // an empty block
  std::swap(bricks.front(), bricks[bricks.size() / 2]);  // not in z, y, x order
  std::vector<std::vector<std::uint8_t>> blocks;
  std::vector<std::uint8_t> reused(4096, 0xab);  // longer than any block here: resized, not appended to
  for (const auto& b : bricks) {
    encodeSplatBlock(b, reused);
    blocks.push_back(reused);
  }
  for (std::size_t i = 0; i < bricks.size(); ++i)
    CHECK(blocks[i].size() == kSplatBrickHeaderBytes + kSplatPointBytes * bricks[i].points.size());
  std::vector<std::span<const std::uint8_t>> spans(blocks.begin(), blocks.end());
  CHECK(joinSplatBlocks(spans) == encodeSplats(bricks));
  CHECK(joinSplatBlocks({}) == encodeSplats({}));
  // After room left for a frame's header: the same buffer behind it.
  const std::vector<std::uint8_t> roomy = joinSplatBlocks(spans, kSplatFormatVersion, 24);
  CHECK(std::vector<std::uint8_t>(roomy.begin() + 24, roomy.end()) == encodeSplats(bricks));
  // The refusals of encodeSplats, and blocks that are not one brick's.
  spans.push_back(blocks[3]);
  CHECK_THROWS_AS(joinSplatBlocks(spans), EngineError);
  spans.pop_back();
  const std::vector<std::uint8_t> cut(blocks[0].begin(), blocks[0].end() - 8), shortHeader(blocks[0].begin(), blocks[0].begin() + 6);
  for (const auto& bad : {cut, shortHeader}) {
    spans[0] = bad;
    CHECK_THROWS_AS(joinSplatBlocks(spans), EngineError);
  }
  CHECK_THROWS_AS(encodeSplatBlock({{-1, 0, 0}, {}}, reused), EngineError);
  BrickSplats nan = bricks[0];
  nan.points[0].x = std::nanf("");
  CHECK_THROWS_AS(encodeSplatBlock(nan, reused), EngineError);
}

TEST_CASE("truncated, padded and corrupted splat buffers are rejected cleanly", "[splats][errors]") {
  const Volume v = makeSphere({24, 24, 24}, {11.7, 12.1, 12.4}, 5);
  auto bricks = extractAllSplats(v);
  bricks.push_back({{2, 2, 2}, {}});
  const auto bytes = encodeSplats(bricks);
  REQUIRE(bytes.size() > 1000);

  for (std::size_t n = 0; n < bytes.size(); ++n)
    REQUIRE(rejectedAsFormat(std::span<const std::uint8_t>(bytes.data(), n)));

  auto longer = bytes;
  longer.push_back(0);
  CHECK(rejectedAsFormat(longer));

  auto badVersion = bytes;
  badVersion[4] = 3;
  CHECK(rejectedAsFormat(badVersion));

  auto badMagic = bytes;
  badMagic[0] = 'X';
  CHECK(rejectedAsFormat(badMagic));

  auto hugeCount = bytes;
  for (int i = 8; i < 12; ++i) hugeCount[std::size_t(i)] = 0xff;
  CHECK(rejectedAsFormat(hugeCount));

  auto hugeBrick = bytes;
  hugeBrick[16 + 6] = 0xff;
  hugeBrick[16 + 7] = 0xff;
  CHECK(rejectedAsFormat(hugeBrick));

  auto twice = bricks;
  twice.back().brick = twice.front().brick;
  CHECK_THROWS_AS(encodeSplats(twice), EngineError);
  auto duplicate = bytes;
  // Rewrite the coordinates of the empty last block to those of the first block.
  const std::size_t last = bytes.size() - 8;
  for (int i = 0; i < 6; ++i) duplicate[last + std::size_t(i)] = bytes[16 + std::size_t(i)];
  CHECK(rejectedAsFormat(duplicate));

  std::mt19937 rng(7);
  int rejected = 0;
  for (int t = 0; t < 3000; ++t) {
    auto bad = bytes;
    const int flips = 1 + int(rng() % 3);
    for (int f = 0; f < flips; ++f) bad[rng() % bad.size()] ^= std::uint8_t(1 + rng() % 255);
    try {
      const auto out = decodeSplats(bad);
      std::size_t n = 0;
      for (const auto& b : out) n += b.points.size();
      REQUIRE(16 + 8 * out.size() + 8 * n == bad.size());
    } catch (const EngineError& e) {
      REQUIRE(e.kind() == ErrorKind::Format);
      ++rejected;
    }
  }
  CHECK(rejected > 0);
}

TEST_CASE("splat extraction refuses bricks outside the grid", "[splats][errors]") {
  const Volume v({40, 40, 40});
  try {
    extractBrickSplats(v, {5, 0, 0});
    FAIL("no error");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::OutOfDomain);
  }
  CHECK_THROWS_AS(extractSplats(v, {{0, 0, 0}, {0, -1, 0}}), EngineError);
  CHECK(extractAllSplats(v).empty());
  CHECK(extractBrickSplats(v, {4, 4, 4}).points.empty());
}

namespace {

const Rgb8 kRed{200, 20, 10};

// Red over the whole surface of v (one dab reaching past every voxel, hard to its edge).
void paintAll(Volume& v, Rgb8 c) {
  PaintSettings st;
  st.color = c;
  st.radius = 1024;
  st.hardness = 0.99;
  paint(v, st, Vec3{double(v.dims().x), double(v.dims().y), double(v.dims().z)} * 0.5);
}

// The bytes of a buffer with two bricks: (1, 2, 3) painted, its point at (9, 17, 25) facing +z
// (codes X = Y = Z = 4096, U = V = 1024) in (200, 20, 10) under mask 255; (0, 0, 0) unpainted,
// its point at (-2, -2, 4) facing -z (codes 0, 0, 8192, U = V = 2047). Written out by hand
// from splats.hpp's table.
const std::vector<std::uint8_t> kGoldenV2 = {
    0x4d, 0x5a, 0x53, 0x50, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00,  // header
    0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x80,                                                  // N = 1 | painted
    0x00, 0x10, 0x00, 0x04, 0x00, 0x01, 0x10, 0x80, 0xc8, 0x14, 0x0a, 0xff,                          // u64, r g b mask
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00,                                                  // N = 1
    0x00, 0x00, 0x00, 0x00, 0x00, 0xfe, 0xff, 0xff};
const std::vector<std::uint8_t> kGoldenV1 = {
    0x4d, 0x5a, 0x53, 0x50, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00,
    0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x00, 0x00, 0x10, 0x00, 0x04, 0x00, 0x01, 0x10, 0x80,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xfe, 0xff, 0xff};

std::vector<BrickSplats> goldenBricks() {
  return {{{1, 2, 3}, {{9, 17, 25, 0, 0, 1}}, {{200, 20, 10, 255}}}, {{0, 0, 0}, {{-2, -2, 4, 0, 0, -1}}, {}}};
}

}  // namespace

TEST_CASE("splats of painted bricks carry the texel of their voxel, unpainted bricks none", "[splats][paint]") {
  Volume v = makeSphere({48, 48, 48}, {23.7, 24.2, 24.1}, 15);
  PaintSettings st;
  st.color = kRed;
  st.radius = 9;
  paint(v, st, {23.7 + 15, 24.2, 24.1});
  st.mode = PaintMode::MaskAdd;
  st.radius = 6;
  paint(v, st, {23.7, 24.2 + 15, 24.1});
  REQUIRE(v.paintedBricks() > 0);
  const auto bricks = extractAllSplats(v);
  // The texels in the order of the points: the surface voxels in index order, brick by brick.
  std::map<Key, std::vector<SplatTexel>> want;
  forEachSurfaceVoxel(v, [&](Int3 p, float, Int3 b) {
    const Texel t = v.texel(p);
    want[key(b)].push_back({t.r, t.g, t.b, t.mask});
  });
  std::size_t painted = 0, red = 0, masked = 0;
  for (const BrickSplats& b : bricks) {
    INFO("brick " << b.brick.x << "," << b.brick.y << "," << b.brick.z);
    if (!v.brickPaint(b.brick)) {
      CHECK(b.texels.empty());
      continue;
    }
    ++painted;
    REQUIRE(b.texels == want[key(b.brick)]);
    for (const SplatTexel& t : b.texels) {
      red += t.r == kRed.r && t.g == kRed.g && t.b == kRed.b;
      masked += t.mask == 255;
    }
  }
  CHECK(painted > 4);
  CHECK(red > 20);
  CHECK(masked > 10);
  // Version 2 keeps them exactly, version 1 drops them.
  std::uint16_t version = 0;
  const auto back = decodeSplats(encodeSplats(bricks), &version);
  CHECK(version == 2);
  REQUIRE(back.size() == bricks.size());
  for (std::size_t i = 0; i < back.size(); ++i) CHECK(back[i].texels == bricks[i].texels);
  for (const BrickSplats& b : decodeSplats(encodeSplats(bricks, 1), &version)) CHECK(b.texels.empty());
  CHECK(version == 1);
}

TEST_CASE("splat buffers of versions 1 and 2, byte for byte", "[splats][paint]") {
  const auto bricks = goldenBricks();
  CHECK(encodeSplats(bricks) == kGoldenV2);
  CHECK(encodeSplats(bricks, 2) == kGoldenV2);
  CHECK(encodeSplats(bricks, 1) == kGoldenV1);
  CHECK(encodedSplatsSize(bricks) == kGoldenV2.size());
  CHECK(encodedSplatsSize(bricks, 1) == kGoldenV1.size());
  CHECK(splatsAsVersion1(kGoldenV2) == kGoldenV1);
  CHECK(splatsAsVersion1(kGoldenV1) == kGoldenV1);
  // Positions at their codes exactly, normals within the octahedral quantization.
  for (const auto* golden : {&kGoldenV2, &kGoldenV1}) {
    const auto back = decodeSplats(*golden);
    REQUIRE(back.size() == 2);
    for (std::size_t i = 0; i < 2; ++i) {
      CHECK(back[i].brick == bricks[i].brick);
      REQUIRE(back[i].points.size() == 1);
      const Splat &a = back[i].points[0], &b = bricks[i].points[0];
      CHECK((a.x == b.x && a.y == b.y && a.z == b.z));
      CHECK(degreesBetween(normal(a), normal(b)) < 0.05);
      CHECK(back[i].texels == (golden == &kGoldenV2 ? bricks[i].texels : std::vector<SplatTexel>{}));
    }
  }
  // Blocks joined in either version are those bytes too.
  std::vector<std::vector<std::uint8_t>> blocks(2);
  for (const std::uint16_t ver : {std::uint16_t(1), std::uint16_t(2)}) {
    for (std::size_t i = 0; i < 2; ++i) encodeSplatBlock(bricks[i], blocks[i], ver);
    CHECK(joinSplatBlocks({blocks[0], blocks[1]}, ver) == (ver == 1 ? kGoldenV1 : kGoldenV2));
  }
  // A version 2 block is not a version 1 block, nor the other way round.
  encodeSplatBlock(bricks[0], blocks[0], 2);
  CHECK_THROWS_AS(joinSplatBlocks({blocks[0]}, 1), EngineError);
  encodeSplatBlock(bricks[0], blocks[0], 1);
  blocks[0][7] = 0x80;  // painted, but 8-byte points
  CHECK_THROWS_AS(joinSplatBlocks({blocks[0]}, 2), EngineError);
  // Texels must be none or one per point; versions are 1 and 2.
  auto wrong = bricks;
  wrong[0].texels.push_back({1, 2, 3, 4});
  CHECK_THROWS_AS(encodeSplats(wrong), EngineError);
  CHECK_THROWS_AS(encodeSplats(bricks, 3), EngineError);
  CHECK_THROWS_AS(encodeSplats(bricks, 0), EngineError);
}

TEST_CASE("inconsistent version 2 splat buffers are rejected cleanly", "[splats][paint][errors]") {
  for (std::size_t n = 0; n < kGoldenV2.size(); ++n)
    REQUIRE(rejectedAsFormat(std::span<const std::uint8_t>(kGoldenV2.data(), n)));
  auto badVersion = kGoldenV2;
  badVersion[4] = 3;
  CHECK(rejectedAsFormat(badVersion));
  // N's unused bits 10..14, each alone, in either block.
  for (const std::size_t at : {std::size_t(16 + 7), std::size_t(16 + 20 + 7)})
    for (int bit = 10; bit <= 14; ++bit) {
      auto bad = kGoldenV2;
      bad[at] = std::uint8_t(bad[at] | (1 << (bit - 8)));
      INFO("byte " << at << " bit " << bit);
      CHECK(rejectedAsFormat(bad));
    }
  // Painted without points.
  const std::vector<std::uint8_t> emptyPainted = {0x4d, 0x5a, 0x53, 0x50, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
                                                  0x00, 0x00, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80};
  CHECK(rejectedAsFormat(emptyPainted));
  auto emptyPlain = emptyPainted;
  emptyPlain[23] = 0;
  CHECK(decodeSplats(emptyPlain).size() == 1);
  // A count above 512 in bits 0..9 (513).
  auto many = kGoldenV2;
  many[16 + 6] = 0x01;
  many[16 + 7] = 0x82;
  CHECK(rejectedAsFormat(many));
  // The painted flag cleared or set makes the lengths disagree.
  auto unflagged = kGoldenV2;
  unflagged[16 + 7] = 0;
  CHECK(rejectedAsFormat(unflagged));
  auto flagged = kGoldenV2;
  flagged[16 + 20 + 7] = 0x80;
  CHECK(rejectedAsFormat(flagged));
  // Version 1 has no flag: its N = 0x8001 claims 32769 points.
  auto v1Flag = kGoldenV1;
  v1Flag[16 + 7] = 0x80;
  CHECK(rejectedAsFormat(v1Flag));
  // Random corruption of a painted sphere's buffer: a refusal or points that re-encode alike.
  Volume v = makeSphere({24, 24, 24}, {11.7, 12.1, 12.4}, 5);
  paintAll(v, kRed);
  const auto bytes = encodeSplats(extractAllSplats(v));
  REQUIRE(bytes.size() > 1000);
  std::mt19937 rng(9);
  int rejected = 0;
  for (int t = 0; t < 3000; ++t) {
    auto bad = bytes;
    const int flips = 1 + int(rng() % 3);
    for (int f = 0; f < flips; ++f) bad[rng() % bad.size()] ^= std::uint8_t(1 + rng() % 255);
    try {
      const auto out = decodeSplats(bad);
      REQUIRE(encodedSplatsSize(out) == bad.size());
    } catch (const EngineError& e) {
      REQUIRE(e.kind() == ErrorKind::Format);
      ++rejected;
    }
  }
  CHECK(rejected > 0);
}

TEST_CASE("the delta of an add-blob stroke over clay painted all over is at most 1.5 times the unpainted one", "[splats][paint]") {
  // The figures of a radius-100 sphere in 256^3 are bench_splats' splats_paint_delta.
  const Volume base = makeSphere({80, 80, 80}, {40, 40, 40}, 30);
  Volume painted = base;
  paintAll(painted, kRed);
  REQUIRE(painted.paintedBricks() > 100);
  auto deltaBytes = [](Volume v) {
    std::vector<StrokeDab> dabs;
    for (int i = 0; i < 12; ++i) {
      const double a = 0.07 * i;
      dabs.emplace_back(Vec3{40 + 30 * std::cos(a), 40 + 30 * std::sin(a), 40});
    }
    const Edit e = applyStroke(v, StrokeSettings(Brush::AddBlob, 8, 1), dabs, {});
    const auto bricks = extractSplats(v, bricksAroundChanges(v, e.changes));
    std::size_t withTexels = 0;
    for (const auto& b : bricks) withTexels += !b.texels.empty();
    return std::pair{encodeSplats(bricks).size(), withTexels};
  };
  const auto [plain, plainPainted] = deltaBytes(base);
  const auto [colour, colourPainted] = deltaBytes(painted);
  INFO("unpainted " << plain << " bytes, painted " << colour << " bytes, ratio " << double(colour) / double(plain));
  CHECK(plainPainted == 0);
  CHECK(colourPainted > 10);
  CHECK(colour > plain);
  CHECK(double(colour) <= 1.5 * double(plain));
}
