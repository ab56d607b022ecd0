// Whole-volume operations run chunk by chunk: the domain is cut into fixed 128^3 chunks
// (brick-aligned and independent of the thread count, so results are bit-identical for any
// number of threads). Each chunk is gathered with a ghost margin, worked on densely, and
// only its interior is written back. Chunks far from every stored brick are skipped: their
// field is uniform and a band-local operation cannot change it. For the same reason only the
// bricks of a chunk within the margin of a stored brick are compared for changes. Each thread
// gathers into its own grid, kept from pass to pass (its pages are not cleared again).
// A Progress installed for the calling thread (progress.hpp) is checked before every chunk
// and advanced by one unit per pass.
#pragma once

#include <functional>
#include <vector>

#include "dense_grid.hpp"
#include "volume.hpp"

namespace marzipan {

class ThreadPool;

inline constexpr int kChunkSide = 128;

// fn(grid, interior, inner) updates grid (the chunk grown by `margin`; the margin may reach
// outside the domain). Chunks run in parallel and get a serial `inner` pool; a lone chunk
// gets the whole pool. Their changes are published together at the end and returned.
using ChunkFn = std::function<void(DenseGrid&, const Box& interior, ThreadPool& inner)>;
std::vector<BrickChange> chunkedPass(Volume& vol, int margin, ThreadPool& pool, const ChunkFn& fn);

}  // namespace marzipan
