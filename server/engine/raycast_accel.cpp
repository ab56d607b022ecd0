// RaycastAccel (raycast.hpp): the brick table and each brick's box of cells that may hold a zero
// and its distances to the nearest such brick, per octant of ray directions, which the kernel
// (raycast_kernel.hpp) reads to jump over empty space.
#include "raycast.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace marzipan {


RaycastAccel::RaycastAccel(const Volume& volume, ThreadPool& pool) : volume_(volume) {
  const Int3 bd = volume_.brickDims();
  const Int3 dims = volume_.dims();
  const float w = volume_.band();

  auto outside = std::make_shared<Brick>();
  auto inside = std::make_shared<Brick>();
  std::fill(std::begin(outside->v), std::end(outside->v), w);
  std::fill(std::begin(inside->v), std::end(inside->v), -w);
  owned_ = {outside, inside};
  bricks_ = BrickGrid<const float*>(bd, 1, outside->v);

  for (int bz = 0; bz < bd.z; ++bz)
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const Int3 b{bx, by, bz};
        float u;
        const float* data = volume_.brickData(b, &u);
        if (data) {
          bricks_[b] = data;
          continue;
        }
        if (u > 0) continue;
        const Box voxels = Bricks::box(b);
        if (voxels.hi.x <= dims.x && voxels.hi.y <= dims.y && voxels.hi.z <= dims.z) {
          bricks_[b] = inside->v;
          continue;
        }
        // A partial brick at the domain's far edge: its voxels past the edge read +band.
        auto edge = std::make_shared<Brick>();
        for (int k = 0; k < kBrickVoxels; ++k) {
          const Int3 p = voxels.lo + Bricks::local(k);
          edge->v[k] = p.x < dims.x && p.y < dims.y && p.z < dims.z ? -w : w;
        }
        bricks_[b] = edge->v;
        owned_.push_back(std::move(edge));
      }

  // The box of each brick's voxels <= 0, local coordinates (none when lo > hi).
  struct VoxelBox {
    std::int8_t lo[3] = {kBrickSide, kBrickSide, kBrickSide}, hi[3] = {-1, -1, -1};
  };
  BrickGrid<VoxelBox> negative(bd, 0);
  pool.parallelFor(std::size_t(bd.z), [&](std::size_t bz) {
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const Int3 b{bx, by, int(bz)};
        const float* v = bricks_[b];
        VoxelBox& box = negative[b];
        if (v == outside->v) continue;
        if (v == inside->v) {
          box = {{0, 0, 0}, {Bricks::kMask, Bricks::kMask, Bricks::kMask}};
          continue;
        }
        int nonPositive = 0;  // a vectorizable first look: most stored bricks have none
        for (int k = 0; k < kBrickVoxels; ++k) nonPositive += v[k] <= 0 ? 1 : 0;
        if (!nonPositive) continue;
        int rows = 0, minX = kBrickSide, maxX = -1;
        for (int z = 0; z < kBrickSide; ++z)
          for (int y = 0; y < kBrickSide; ++y) {
            const float* row = v + Bricks::index(0, y, z);
            unsigned mask = 0;
            for (int x = 0; x < kBrickSide; ++x) mask |= unsigned(row[x] <= 0) << x;
            if (!mask) continue;
            ++rows;
            minX = std::min(minX, std::countr_zero(mask));
            maxX = std::max(maxX, 31 - std::countl_zero(mask));
            box.lo[1] = std::int8_t(std::min<int>(box.lo[1], y)), box.hi[1] = std::int8_t(std::max<int>(box.hi[1], y));
            box.lo[2] = std::int8_t(std::min<int>(box.lo[2], z)), box.hi[2] = std::int8_t(std::max<int>(box.hi[2], z));
          }
        if (rows) box.lo[0] = std::int8_t(minX), box.hi[0] = std::int8_t(maxX);
      }
  });

  // A voxel <= 0 puts a possible zero in the 8 cells it is a corner of, so a brick's box grows
  // by one cell downwards, into the bricks below it along each axis.
  info_ = BrickGrid<BrickInfo>(bd, 1, BrickInfo{255, {}, {kBrickSide, kBrickSide, kBrickSide}, {0, 0, 0}});
  for (int bz = 0; bz < bd.z; ++bz)
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const VoxelBox& box = negative[Int3{bx, by, bz}];
        if (box.lo[0] > box.hi[0]) continue;
        const Int3 o = Bricks::origin({bx, by, bz});
        int cellLo[3], cellHi[3];
        for (int k = 0; k < 3; ++k) cellLo[k] = o[k] + box.lo[k] - 1, cellHi[k] = o[k] + box.hi[k];
        for (int dz = -1; dz <= 0; ++dz)
          for (int dy = -1; dy <= 0; ++dy)
            for (int dx = -1; dx <= 0; ++dx) {
              const Int3 nb{bx + dx, by + dy, bz + dz};
              const Int3 no = Bricks::origin(nb);
              int lo[3], hi[3];
              bool any = true;
              for (int k = 0; k < 3; ++k) {
                lo[k] = std::max(cellLo[k], no[k]) - no[k];
                hi[k] = std::min(cellHi[k], no[k] + Bricks::kMask) - no[k];
                any = any && lo[k] <= hi[k];
              }
              if (!any) continue;
              BrickInfo& info = info_[nb];
              info.reach = 0;
              for (int k = 0; k < 3; ++k) {
                info.lo[k] = std::uint8_t(std::min<int>(info.lo[k], lo[k]));
                info.hi[k] = std::uint8_t(std::max<int>(info.hi[k], hi[k]));
              }
            }
      }

  // Per octant of ray directions, the chessboard distance in bricks to the nearest brick with
  // such cells among those a ray of the octant can still enter (none at a lower index along an
  // axis it goes up, none at a higher one along an axis it goes down): a forward chessboard
  // transform, one raster pass against the octant, exact because every brick of that region is
  // reached by king moves into it. Per brick, a pass takes the 7 neighbours into the octant: 2
  // in each of the 3 rows already done (gathered a row at a time), then the row's previous
  // brick, the only sequential dependency. The plain distance, for the tile cones, is the
  // smallest of the 8.
  const Int3 p = bd + Int3{2, 2, 2};  // the table, its ring included
  const std::size_t n = info_.size(), sy = info_.strideY(), sz = info_.strideZ();
  std::vector<std::uint8_t> seed(n), reach(n);
  for (std::size_t i = 0; i < n; ++i) seed[i] = info_[i].reach;
  std::vector<std::uint8_t> near(std::size_t(p.x));
  for (int octant = 0; octant < 8; ++octant) {
    const int s[3] = {octant & 1 ? -1 : 1, octant & 2 ? -1 : 1, octant & 4 ? -1 : 1};
    // The x range where the neighbour x + s[0] is in the table too; the other end brick has only x.
    const int xLo = s[0] > 0 ? 0 : 1, xHi = s[0] > 0 ? p.x - 1 : p.x, xEdge = s[0] > 0 ? p.x - 1 : 0;
    for (int zi = 0; zi < p.z; ++zi) {
      const int z = s[2] > 0 ? p.z - 1 - zi : zi, zn = z + s[2];
      for (int yi = 0; yi < p.y; ++yi) {
        const int y = s[1] > 0 ? p.y - 1 - yi : yi, yn = y + s[1];
        std::fill(near.begin(), near.end(), std::uint8_t(255));
        for (const auto& [ry, rz] : {std::pair{yn, z}, std::pair{y, zn}, std::pair{yn, zn}}) {
          if (ry < 0 || ry >= p.y || rz < 0 || rz >= p.z) continue;
          const std::uint8_t* row = &reach[sy * std::size_t(ry) + sz * std::size_t(rz)];
          std::uint8_t* out = near.data();
          for (int x = xLo; x < xHi; ++x)
            out[x] = std::min<std::uint8_t>(out[x], std::min<std::uint8_t>(std::min(row[x], row[x + s[0]]), 254) + 1);
          out[xEdge] = std::min<std::uint8_t>(out[xEdge], std::min<std::uint8_t>(row[xEdge], 254) + 1);
        }
        const std::size_t base = sy * std::size_t(y) + sz * std::size_t(z);
        int prev = 255;
        for (int xi = 0; xi < p.x; ++xi) {
          const int x = s[0] > 0 ? p.x - 1 - xi : xi;
          prev = seed[base + x] ? std::min({int(near[std::size_t(x)]), prev + 1, 255}) : 0;
          reach[base + x] = std::uint8_t(prev);
        }
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      info_[i].octant[octant] = reach[i];
      info_[i].reach = octant ? std::min(info_[i].reach, reach[i]) : reach[i];
    }
  }
}

}  // namespace marzipan
