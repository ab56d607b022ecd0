// The motion driver: moves the listed voxels (listing.cpp) by their speeds under a Motion,
// sub-step by sub-step, calling the stepping kernels (kernels.hpp) per block or z-slice of
// runs. Advection's two sub-steps write a list and copy it back; smoothing's many curvature
// sub-steps alternate between two copies of the grid, in waves over the z-slices on one
// thread, or in pieces of whole z-slices that the threads take as their neighbours are ready.
// Work is cut in fixed pieces and each voxel's value computed alone, so the field does not
// depend on the thread count or the order. Separate from the kernels: this is scheduling (the
// pool, the cache, progress), they are arithmetic.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <thread>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "engine/simd_width.hpp"

#include "engine/level_set/internal.hpp"
#include "engine/level_set/kernels.hpp"

namespace marzipan::level_set {

namespace {

// The m.substeps curvature steps of evolve between g.v and s.other, on the pool without waking
// it for each step. The steps read the runs' slices and the slices next to them (a run's last
// lanes up to 4 voxels past it): each piece copies its part of that into s.other before its
// first step, the pieces next to it only read there once they have done theirs. The runs are cut into pieces of whole z-slices; a
// voxel's neighbours then lie in its own piece or the two next to it. Step j of piece p reads
// the grid that holds step j - 1 and writes the other, over step j - 2: it may run once its
// neighbours have done step j - 1 (what it reads is there, and they are done reading step
// j - 2), so neighbours only ever run the same step at once, reading one grid and writing
// the other at their own voxels. Threads take whichever piece is ready, lowest step first;
// each voxel's value is computed as in a plain loop over the steps, so the result is the
// same for any thread count and any order.
void curvatureSteps(DenseGrid& g, ToolScratch& s, const Motion& m, ThreadPool& pool, const ProgressShare& progress) {
  const std::vector<Run>& runs = s.moved.runs;
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  float* const grids[2] = {g.v.data(), s.other.data()};
  constexpr std::size_t kPieceVoxels = 2048;
  std::vector<std::size_t>& pieces = s.blocks;  // the first run of each piece, then runs.size()
  pieces.clear();
  for (std::size_t r = 0, inPiece = kPieceVoxels; r < runs.size(); ++r) {
    if (inPiece >= kPieceVoxels && (r == 0 || runs[r].index / g.sxy != runs[r - 1].index / g.sxy)) {
      pieces.push_back(r);
      inPiece = 0;
    }
    inPiece += runs[r].count;
  }
  pieces.push_back(runs.size());
  const int count = int(pieces.size()) - 1, steps = m.substeps;
  // Piece p copies [copyFrom(p), copyFrom(p + 1)): from the slice before the runs (the first)
  // or its first run's slice, to the next piece's, or past the last run's slice (the last).
  auto copyFrom = [&](int p) {
    if (p == 0) return std::size_t(runs.front().index) - g.sxy;
    if (p == count) return std::size_t(runs.back().index) + runs.back().count + 4 + g.sxy;
    return runs[pieces[std::size_t(p)]].index / g.sxy * g.sxy;
  };
  auto runStep = [&](int p, int step, bool copy) {  // step 0-based: reads grids[step % 2]
    if (step == 0 && copy)
      std::copy(g.v.begin() + std::ptrdiff_t(copyFrom(p)), g.v.begin() + std::ptrdiff_t(copyFrom(p + 1)),
                s.other.begin() + std::ptrdiff_t(copyFrom(p)));
    curvatureRuns(grids[step % 2], grids[(step + 1) % 2], true, runs.data() + pieces[std::size_t(p)],
                  runs.data() + pieces[std::size_t(p) + 1], s.moved.factor.data(), sy, sz, m.curvatureLimit);
  };
  // Below 8192 voxels (a brush of radius ~10) a step is a few microseconds: the threads would
  // mostly wait for each other, and a woken thread that loses its core holds up the rest.
  constexpr std::uint32_t kParallelVoxels = 8192;
  const int participants = s.moved.count < kParallelVoxels ? 1 : std::min(pool.threads(), count);
  if (participants <= 1) {
    // On one thread s.other needs, before the first step, only what the steps read there and
    // do not write: the listed voxels' neighbours and the lanes past a run's end (x - 1 to
    // x + count + 3 along the run's row, x to x + count + 2 along the four rows next to it),
    // not the whole slices (a 70^3 brush's grid is 1.9 MB, its band's neighbourhood a fraction).
    // Pieces of four, which may copy up to 3 more voxels past those (in the grid: the region
    // lies kStencilReach inside it).
    auto copyRow = [&](std::size_t from, std::size_t n) {
      const float* src = g.v.data() + from;
      float* dst = s.other.data() + from;
#if defined(MARZIPAN_SSE2)
      for (std::size_t k = 0; k < n; k += 4) _mm_storeu_ps(dst + k, _mm_loadu_ps(src + k));
#else
      std::copy_n(src, n, dst);
#endif
    };
    for (const Run& r : runs) {
      copyRow(r.index - 1, r.count + 5);
      for (const std::size_t o : {r.index - g.sx, r.index + g.sx, r.index - g.sxy, r.index + g.sxy})
        copyRow(o, r.count + 3);
    }
    // The steps in bands of kWave, each band one sweep over the z-slices: step b + j of slice
    // piece q runs at time q + 2j, after its neighbours' step b + j - 1 (time q + 2j - 1) and
    // before their step b + j + 1 (time q + 2j + 1 or later), which is the rule above. A sweep
    // then keeps about 2 kWave slices of both copies in the cache, where step by step each
    // step read the whole band's neighbourhood (megabytes at 70^3) from memory again.
    constexpr int kWave = 4;
    std::vector<std::size_t>& slices = s.slices;
    slices.clear();
    for (std::size_t r = 0; r < runs.size(); ++r)
      if (r == 0 || runs[r].index / g.sxy != runs[r - 1].index / g.sxy) slices.push_back(r);
    slices.push_back(runs.size());
    const int n = int(slices.size()) - 1;
    for (int b = 0; b < steps; b += kWave) {
      progress.check();
      const int k = std::min(kWave, steps - b);
      for (int t = 0; t < n + 2 * (k - 1); ++t)
        for (int j = 0; j < k; ++j)
          if (const int q = t - 2 * j; q >= 0 && q < n) {
            const int step = b + j;
            curvatureRuns(grids[step % 2], grids[(step + 1) % 2], true, runs.data() + slices[std::size_t(q)],
                          runs.data() + slices[std::size_t(q) + 1], s.moved.factor.data(), sy, sz, m.curvatureLimit);
          }
      progress.advance(double(k) / steps);
    }
    return;
  }
  // done[p]: steps piece p has finished; claimed[p]: a thread is running its next step.
  std::unique_ptr<std::atomic<int>[]> done(new std::atomic<int>[std::size_t(count)]);
  std::unique_ptr<std::atomic<bool>[]> claimed(new std::atomic<bool>[std::size_t(count)]);
  for (int p = 0; p < count; ++p) {
    done[std::size_t(p)].store(0, std::memory_order_relaxed);
    claimed[std::size_t(p)].store(false, std::memory_order_relaxed);
  }
  std::atomic<int> finished{0};
  std::atomic<bool> failed{false};
  auto ready = [&](int p, int d) {
    return (p == 0 || done[std::size_t(p - 1)].load(std::memory_order_acquire) >= d) &&
           (p + 1 == count || done[std::size_t(p + 1)].load(std::memory_order_acquire) >= d);
  };
  pool.parallelFor(std::size_t(participants), [&](std::size_t) {
    int idle = 0;
    while (finished.load(std::memory_order_acquire) < count && !failed.load(std::memory_order_relaxed)) {
      int best = -1, bestStep = steps;
      for (int p = 0; p < count; ++p) {
        const int d = done[std::size_t(p)].load(std::memory_order_acquire);
        if (d < bestStep && !claimed[std::size_t(p)].load(std::memory_order_relaxed) && ready(p, d)) {
          best = p;
          bestStep = d;
        }
      }
      bool mine = false;
      if (best >= 0 && claimed[std::size_t(best)].compare_exchange_strong(mine, true, std::memory_order_acq_rel)) {
        // Another thread may have run a step of it between the scan and the claim.
        const int d = done[std::size_t(best)].load(std::memory_order_acquire);
        // Whatever throws (a cancel, the progress report), the claim is let go and the other
        // threads stop instead of waiting for this piece.
        try {
          if (d < steps && ready(best, d)) {
            progress.check();
            runStep(best, d, true);
            done[std::size_t(best)].store(d + 1, std::memory_order_release);
            if (d + 1 == steps) finished.fetch_add(1, std::memory_order_acq_rel);
            claimed[std::size_t(best)].store(false, std::memory_order_release);
            progress.advance(1.0 / (double(steps) * count));
            idle = 0;
          } else {
            claimed[std::size_t(best)].store(false, std::memory_order_release);
          }
        } catch (...) {
          failed.store(true, std::memory_order_relaxed);
          claimed[std::size_t(best)].store(false, std::memory_order_release);
          throw;
        }
        continue;
      }
      // Nothing ready: the pieces next to the ones left are being worked on by another thread.
      if (++idle < 64) {
#if defined(MARZIPAN_SSE2)
        _mm_pause();
#endif
      } else {
        std::this_thread::yield();
      }
    }
  });
}

}  // namespace

void moveListed(DenseGrid& g, const Motion& m, ThreadPool& pool, const ProgressShare& progress) {
  ToolScratch& s = toolScratch();
  MovedVoxels& moved = s.moved;
  const std::vector<Run>& runs = moved.runs;
  const bool curvature = m.kind == Motion::Kind::Curvature;
  const std::size_t stride[3] = {1, g.sx, g.sxy};
  if (runs.empty()) {
    progress.advance(1);
    return;
  }
  // The kernels read up to 3 entries past the last run.
  moved.factor.resize(moved.factor.size() + 3, 0.0);
  moved.step.resize(moved.step.size() + 3, 0.0f);
  std::vector<float>& next = s.next;
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  // Many curvature sub-steps (smoothing's 32): each reads one copy of the grid and writes the
  // other, which holds the same values off the list, instead of writing a list and copying it
  // back every sub-step. An even count ends in g.v. (curvatureSteps runs the curvature kernel
  // only: advection in as many sub-steps takes the blocks below.)
  if (curvature && m.substeps > 2 && m.substeps % 2 == 0) {
    s.other.resize(g.v.size());
    curvatureSteps(g, s, m, pool, progress);
    return;
  }
  // Fixed blocks of whole runs, each of at least kBlock voxels but the last.
  constexpr std::size_t kBlock = 4096;
  std::vector<std::size_t>& blocks = s.blocks;
  blocks.clear();
  for (std::size_t r = 0, inBlock = kBlock; r < runs.size(); ++r) {
    if (inBlock >= kBlock) {
      blocks.push_back(r);
      inBlock = 0;
    }
    inBlock += runs[r].count;
  }
  blocks.push_back(runs.size());
  next.resize(moved.count);
  for (int step = 0; step < m.substeps; ++step) {
    pool.parallelFor(blocks.size() - 1, [&](std::size_t b) {
      progress.check();
      const Run* first = runs.data() + blocks[b];
      const Run* last = runs.data() + blocks[b + 1];
      if (curvature) {
        curvatureRuns(g.v.data(), next.data(), false, first, last, moved.factor.data(), sy, sz, m.curvatureLimit);
      } else {
        advectionRuns(g.v.data(), next.data(), first, last, moved.step.data(), stride);
      }
    });
    for (const Run& r : runs) std::copy_n(next.data() + r.first, r.count, g.v.data() + r.index);
    progress.advance(1.0 / m.substeps);
  }
}

Box listedBounds(const DenseGrid& g, const MovedVoxels& moved, float leastStep) {
  Box b{{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(), std::numeric_limits<int>::max()},
        {std::numeric_limits<int>::min(), std::numeric_limits<int>::min(), std::numeric_limits<int>::min()}};
  const bool all = !(leastStep > 0) || moved.step.empty();
  for (const Run& r : moved.runs) {
    std::uint32_t lo = 0, hi = r.count;  // the run's voxels [lo, hi) that count
    if (!all) {
      const float* step = moved.step.data() + r.first;
      while (lo < hi && !(std::fabs(step[lo]) > leastStep)) ++lo;
      while (hi > lo && !(std::fabs(step[hi - 1]) > leastStep)) --hi;
      if (lo == hi) continue;
    }
    const Int3 first = g.point(r.index);  // a run lies in one row
    b.lo = {std::min(b.lo.x, first.x + int(lo)), std::min(b.lo.y, first.y), std::min(b.lo.z, first.z)};
    b.hi = {std::max(b.hi.x, first.x + int(hi)), std::max(b.hi.y, first.y + 1), std::max(b.hi.z, first.z + 1)};
  }
  return b;
}

void evolve(DenseGrid& g, const Box& region, float band, const Motion& m, const SweptWindow* window,
            const BandVoxels& voxels, ThreadPool& pool, const ProgressShare& progress) {
  listMoved(g, region, band, &m, window, voxels, pool, progress);
  moveListed(g, m, pool, progress);
}

}  // namespace marzipan::level_set
