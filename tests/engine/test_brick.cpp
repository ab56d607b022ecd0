#include <catch2/catch.hpp>

#include <set>
#include <vector>

#include "engine/brick.hpp"
#include "engine/solids.hpp"
#include "engine/volume.hpp"

using namespace marzipan;

// The layout for other brick sides than the engine's: changing kBrickLog2 is a one-line change,
// and these are the sides it may be changed to.
TEMPLATE_TEST_CASE("brick addressing splits a voxel into brick and local voxel, negatives included", "[brick]",
                   BrickLayout<1>, BrickLayout<2>, BrickLayout<3>, BrickLayout<4>, BrickLayout<5>) {
  using L = TestType;
  STATIC_REQUIRE(L::kSide == (1 << L::kLog2));
  STATIC_REQUIRE(L::kVoxels == L::kSide * L::kSide * L::kSide);
  for (int c = -3 * L::kSide; c < 3 * L::kSide; ++c) {
    const int b = L::brickOf(c), l = L::localOf(c);
    INFO("coordinate " << c);
    REQUIRE(l >= 0);
    REQUIRE(l < L::kSide);
    REQUIRE(b * L::kSide + l == c);
    // Rounding down, like floor(c / side): the voxel before the origin is in brick -1.
    REQUIRE(b == (c >= 0 ? c / L::kSide : -((-c + L::kSide - 1) / L::kSide)));
  }
  CHECK(L::brickOf(Int3{-1, 0, L::kSide}) == Int3{-1, 0, 1});
  CHECK(L::localOf(Int3{-1, 0, L::kSide}) == Int3{L::kSide - 1, 0, 0});
}

TEMPLATE_TEST_CASE("a brick's local voxels have distinct indices, x fastest", "[brick]", BrickLayout<1>,
                   BrickLayout<2>, BrickLayout<3>, BrickLayout<4>) {
  using L = TestType;
  std::vector<int> seen(std::size_t(L::kVoxels), 0);
  int expected = 0;
  for (int z = 0; z < L::kSide; ++z)
    for (int y = 0; y < L::kSide; ++y)
      for (int x = 0; x < L::kSide; ++x, ++expected) {
        const int i = L::index(x, y, z);
        REQUIRE(i == expected);
        REQUIRE(L::local(i) == Int3{x, y, z});
        // Any voxel of brick (2, -1, 3) at this local voxel has this index.
        const Int3 p = L::origin(Int3{2, -1, 3}) + Int3{x, y, z};
        REQUIRE(L::indexOf(p) == i);
        REQUIRE(L::box(Int3{2, -1, 3}).contains(p));
        ++seen[std::size_t(i)];
      }
  for (const int s : seen) REQUIRE(s == 1);
  CHECK(L::kRowBits == (L::kSide == 32 ? ~0u : (1u << L::kSide) - 1));
}

TEMPLATE_TEST_CASE("the bricks covering a domain and meeting a box round outwards", "[brick]", BrickLayout<2>,
                   BrickLayout<3>, BrickLayout<4>) {
  using L = TestType;
  const int s = L::kSide;
  CHECK(L::gridOf(Int3{s, s + 1, 3 * s - 1}) == Int3{1, 2, 3});
  const Box b = L::bricksOf(Box{{-1, 0, s - 1}, {1, s + 1, s}});
  CHECK(b.lo == Int3{-1, 0, 0});
  CHECK(b.hi == Int3{1, 2, 1});
}

TEST_CASE("the engine's bricks follow the layout of kBrickLog2", "[brick][volume]") {
  STATIC_REQUIRE(kBrickSide == Bricks::kSide);
  STATIC_REQUIRE(sizeof(Brick) == sizeof(float) * std::size_t(Bricks::kVoxels));
  // A volume whose sides are not multiples of the brick side: partial bricks at the far edges.
  const Int3 dims{3 * kBrickSide + 3, 2 * kBrickSide + 1, 2 * kBrickSide};
  Volume vol = makeSphere(dims, {13.0, 8.5, 8.0}, 7.0);
  CHECK(vol.brickDims() == Bricks::gridOf(dims));
  int stored = 0;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const Int3 p{x, y, z};
        float u;
        const float* d = vol.brickData(Bricks::brickOf(p), &u);
        stored += d ? 1 : 0;
        REQUIRE(vol.at(p) == (d ? d[Bricks::indexOf(p)] : u));
      }
  CHECK(stored > 0);
}

TEST_CASE("a brick grid has one slot per brick of the grid and its ring", "[brick]") {
  const Int3 grid{3, 2, 4};
  BrickGrid<int> g(grid, 1, -7);
  CHECK(g.size() == std::size_t(5 * 4 * 6));
  CHECK(g.strideY() == 5);
  CHECK(g.strideZ() == 20);
  std::set<std::size_t> indices;
  for (int z = -1; z <= grid.z; ++z)
    for (int y = -1; y <= grid.y; ++y)
      for (int x = -1; x <= grid.x; ++x) {
        const Int3 b{x, y, z};
        REQUIRE(g.contains(b));
        REQUIRE(g.inGrid(b) == (x >= 0 && y >= 0 && z >= 0 && x < grid.x && y < grid.y && z < grid.z));
        REQUIRE(g[b] == -7);
        REQUIRE(g.index(b) < g.size());
        indices.insert(g.index(b));
        g[b] = x + 10 * y + 100 * z;
      }
  CHECK(indices.size() == g.size());
  CHECK(g[Int3{-1, -1, -1}] == -111);
  CHECK(g[Int3{2, 1, 3}] == 312);
  CHECK(g.index(Int3{1, 0, 0}) == g.index(Int3{0, 0, 0}) + 1);
  CHECK(!g.contains(Int3{-2, 0, 0}));
  CHECK(!g.contains(Int3{0, grid.y + 1, 0}));
  BrickGrid<char> bare(grid, 0);
  CHECK(bare.size() == std::size_t(grid.x * grid.y * grid.z));
  CHECK(bare.index(Int3{0, 0, 0}) == 0);
}
