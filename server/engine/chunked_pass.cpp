#include "chunked_pass.hpp"

#include "brick.hpp"
#include "progress.hpp"
#include "thread_pool.hpp"

namespace marzipan {

std::vector<BrickChange> chunkedPass(Volume& vol, int margin, ThreadPool& pool, const ChunkFn& fn) {
  const Int3 dims = vol.dims();
  const Box brickGrid{{0, 0, 0}, vol.brickDims()};
  const int marginBricks = Bricks::gridOf({margin, margin, margin}).x;  // whole bricks covering the margin

  // A chunk is active when a stored brick lies within its margin.
  std::vector<Box> chunks;
  for (int cz = 0; cz < dims.z; cz += kChunkSide)
    for (int cy = 0; cy < dims.y; cy += kChunkSide)
      for (int cx = 0; cx < dims.x; cx += kChunkSide) {
        const Box chunk{{cx, cy, cz}, {cx + kChunkSide, cy + kChunkSide, cz + kChunkSide}};
        const Box interior = chunk.intersect(vol.domain());
        const Box near = Bricks::bricksOf(chunk).grown(marginBricks).intersect(brickGrid);
        bool active = false;
        for (int bz = near.lo.z; !active && bz < near.hi.z; ++bz)
          for (int by = near.lo.y; !active && by < near.hi.y; ++by)
            for (int bx = near.lo.x; !active && bx < near.hi.x; ++bx) {
              float u;
              active = vol.brickData({bx, by, bz}, &u) != nullptr;
            }
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
    DenseGrid g = DenseGrid::gather(source, chunks[c].grown(margin));
    fn(g, chunks[c], inner);
    perChunk[c] = source.diff(chunks[c], g.v.data(), g.box);
    if (progress) progress->advance(1.0 / double(chunks.size()));
  };
  if (chunks.size() == 1) {
    run(0, pool);
  } else {
    pool.parallelFor(chunks.size(), [&](std::size_t c) { run(c, ThreadPool::serial()); });
  }

  if (chunks.empty() && progress) progress->advance(1);
  std::vector<BrickChange> changes;
  for (auto& pc : perChunk) changes.insert(changes.end(), pc.begin(), pc.end());
  vol.publish(changes, true);
  return changes;
}

}  // namespace marzipan
