#include <catch2/catch.hpp>

#include "engine/brick_table.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

TEST_CASE("a brick table reads what the volume holds, brick by brick and voxel by voxel", "[brick]") {
  // A box filling whole bricks (uniformly inside slots) in a domain with partial bricks.
  const Int3 dims{45, 40, 33};
  const Volume vol = makeBox(dims, {22.0, 20.0, 16.0}, {14.0, 12.0, 11.0});
  const BrickTable table(vol);
  const Int3 n = vol.brickDims();
  int kinds[3] = {0, 0, 0};
  for (int z = -1; z <= n.z; ++z)
    for (int y = -1; y <= n.y; ++y)
      for (int x = -1; x <= n.x; ++x) {
        const Int3 b{x, y, z};
        float u = 0;
        const float* d = table.data(b, &u);
        const BrickTable::Kind k = table.kind(b);
        ++kinds[int(k)];
        REQUIRE(table.inGrid(b) == (x >= 0 && y >= 0 && z >= 0 && x < n.x && y < n.y && z < n.z));
        if (!table.inGrid(b)) {
          REQUIRE(d == nullptr);
          REQUIRE(u == vol.band());
          REQUIRE(k == BrickTable::Kind::Outside);
          continue;
        }
        const BrickRef ref = vol.brick(b);
        REQUIRE(d == (ref.data ? ref.data->v : nullptr));
        REQUIRE(k == (ref.data ? BrickTable::Kind::Stored : ref.inside ? BrickTable::Kind::Inside : BrickTable::Kind::Outside));
        if (!d) REQUIRE(u == (ref.inside ? -vol.band() : vol.band()));
      }
  CHECK(kinds[int(BrickTable::Kind::Inside)] > 0);
  CHECK(kinds[int(BrickTable::Kind::Stored)] > 0);
  for (int z = -2; z < dims.z + 2; ++z)
    for (int y = -2; y < dims.y + 2; ++y)
      for (int x = -2; x < dims.x + 2; ++x) REQUIRE(table.at({x, y, z}) == vol.at({x, y, z}));
}
