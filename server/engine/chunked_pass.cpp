#include "chunked_pass.hpp"

#include "progress.hpp"
#include "thread_pool.hpp"

namespace marzipan {

std::vector<BrickChange> chunkedPass(Volume& vol, int margin, ThreadPool& pool, const ChunkFn& fn) {
  const Int3 dims = vol.dims();
  const Int3 bd = vol.brickDims();
  const int marginBricks = (margin + kBrickSide - 1) / kBrickSide;
  constexpr int chunkBricks = kChunkSide / kBrickSide;

  // A chunk is active when a stored brick lies within its margin.
  std::vector<Box> chunks;
  for (int cz = 0; cz < dims.z; cz += kChunkSide)
    for (int cy = 0; cy < dims.y; cy += kChunkSide)
      for (int cx = 0; cx < dims.x; cx += kChunkSide) {
        const Box interior = Box{{cx, cy, cz}, {cx + kChunkSide, cy + kChunkSide, cz + kChunkSide}}.intersect(vol.domain());
        const Int3 blo{cx / kBrickSide - marginBricks, cy / kBrickSide - marginBricks, cz / kBrickSide - marginBricks};
        bool active = false;
        for (int bz = std::max(0, blo.z); !active && bz < std::min(bd.z, blo.z + chunkBricks + 2 * marginBricks); ++bz)
          for (int by = std::max(0, blo.y); !active && by < std::min(bd.y, blo.y + chunkBricks + 2 * marginBricks); ++by)
            for (int bx = std::max(0, blo.x); !active && bx < std::min(bd.x, blo.x + chunkBricks + 2 * marginBricks); ++bx) {
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
