#include "chunked_pass.hpp"

#include <algorithm>

#include "brick.hpp"
#include "progress.hpp"
#include "thread_pool.hpp"

namespace marzipan {

namespace {

// Per brick of the volume: 1 when a stored brick lies within `reach` bricks of it (in every
// axis), x fastest. Such bricks are the only ones a band-local pass whose margin is covered
// by `reach` whole bricks can change: everything it reads around any other brick is uniform.
std::vector<std::uint8_t> nearStored(const Volume& vol, int reach) {
  const Int3 n = vol.brickDims();
  const std::size_t sx = std::size_t(n.x), sxy = sx * std::size_t(n.y);
  std::vector<std::uint8_t> a(sxy * std::size_t(n.z)), b(a.size());
  for (int bz = 0; bz < n.z; ++bz)
    for (int by = 0; by < n.y; ++by)
      for (int bx = 0; bx < n.x; ++bx) {
        float u;
        a[std::size_t(bx) + sx * std::size_t(by) + sxy * std::size_t(bz)] = vol.brickData({bx, by, bz}, &u) != nullptr;
      }
  // A box filter (max) of half-width reach, one axis at a time.
  const std::size_t stride[3] = {1, sx, sxy};
  for (int axis = 0; axis < 3; ++axis) {
    const int len = n[axis];
    for (std::size_t i = 0; i < a.size(); ++i) {
      const int at = int((i / stride[axis]) % std::size_t(len));
      const int lo = std::max(0, at - reach), hi = std::min(len - 1, at + reach);
      std::uint8_t any = 0;
      for (int k = lo; k <= hi && !any; ++k) any = a[i + stride[axis] * std::size_t(k) - stride[axis] * std::size_t(at)];
      b[i] = any;
    }
    a.swap(b);
  }
  return a;
}

// Each thread's chunk grid, reused from pass to pass: a fresh one costs as much in page
// clearing as the gather itself.
DenseGrid& chunkGrid() {
  thread_local DenseGrid g;
  return g;
}

}  // namespace

std::vector<BrickChange> chunkedPass(Volume& vol, int margin, ThreadPool& pool, const ChunkFn& fn) {
  const Int3 dims = vol.dims();
  const Int3 nb = vol.brickDims();
  const int marginBricks = Bricks::gridOf({margin, margin, margin}).x;  // whole bricks covering the margin
  const std::vector<std::uint8_t> near = nearStored(vol, marginBricks);
  auto isNear = [&](int bx, int by, int bz) {
    return near[std::size_t(bx) + std::size_t(nb.x) * (std::size_t(by) + std::size_t(nb.y) * std::size_t(bz))] != 0;
  };

  // A chunk is active when a stored brick lies within its margin.
  std::vector<Box> chunks;
  for (int cz = 0; cz < dims.z; cz += kChunkSide)
    for (int cy = 0; cy < dims.y; cy += kChunkSide)
      for (int cx = 0; cx < dims.x; cx += kChunkSide) {
        const Box chunk{{cx, cy, cz}, {cx + kChunkSide, cy + kChunkSide, cz + kChunkSide}};
        const Box interior = chunk.intersect(vol.domain());
        const Box bricks = Bricks::bricksOf(interior);
        bool active = false;
        for (int bz = bricks.lo.z; !active && bz < bricks.hi.z; ++bz)
          for (int by = bricks.lo.y; !active && by < bricks.hi.y; ++by)
            for (int bx = bricks.lo.x; !active && bx < bricks.hi.x; ++bx) active = isNear(bx, by, bz);
        if (active) chunks.push_back(interior);
      }

  // The caller's Progress (progress.hpp): checked before each chunk, one pass counts as one
  // unit. Nothing is published before every chunk is done, so a cancelled pass leaves vol alone.
  Progress* progress = Progress::current();
  if (progress) progress->check();
  std::vector<std::vector<BrickChange>> perChunk(chunks.size());
  const Volume& source = vol;
  auto run = [&](std::size_t c, ThreadPool& inner) {
    if (progress) progress->check();
    DenseGrid& g = chunkGrid();
    g.gatherFrom(source, chunks[c].grown(margin));
    fn(g, chunks[c], inner);
    // Only bricks near a stored one can have changed: compare those, run by run of a brick
    // row, in the order a diff of the whole chunk would list them.
    const Box bricks = Bricks::bricksOf(chunks[c]);
    std::vector<BrickChange>& out = perChunk[c];
    out.clear();
    for (int bz = bricks.lo.z; bz < bricks.hi.z; ++bz)
      for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
        for (int bx = bricks.lo.x; bx < bricks.hi.x;) {
          if (!isNear(bx, by, bz)) {
            ++bx;
            continue;
          }
          const int first = bx;
          while (bx < bricks.hi.x && isNear(bx, by, bz)) ++bx;
          const Box span = Box{Bricks::origin({first, by, bz}), Bricks::origin({bx, by + 1, bz + 1})}.intersect(chunks[c]);
          std::vector<BrickChange> changed = source.diff(span, g.v.data(), g.box);
          out.insert(out.end(), std::make_move_iterator(changed.begin()), std::make_move_iterator(changed.end()));
        }
    if (progress) progress->advance(1.0 / double(chunks.size()));
  };
  if (chunks.size() == 1) {
    run(0, pool);
  } else {
    pool.parallelFor(chunks.size(), [&](std::size_t c) { run(c, ThreadPool::serial()); });
  }

  if (chunks.empty() && progress) progress->advance(1);
  std::vector<BrickChange> changes;
  for (auto& pc : perChunk) changes.insert(changes.end(), std::make_move_iterator(pc.begin()), std::make_move_iterator(pc.end()));
  vol.extendChannels(changes);
  vol.publish(changes, true);
  return changes;
}

}  // namespace marzipan
