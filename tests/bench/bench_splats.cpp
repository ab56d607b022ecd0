// Splat benchmarks: full extraction plus encoding of a sphere (radius 100 in 256^3; radius 30
// in 80^3 with --quick), on one thread and on the requested thread count. Extraction alone is
// reported as extract_ms (median over the same repetitions). splats_delta: what the hub sends
// after each dab (radius 8, add blob, at random points of the same sphere): the bricks around
// the changes, their splats, and the buffer of those whose encoding differs from what the
// session's clients were sent (HeldSplats, service/hub/broadcast.hpp), on one thread (the hub's
// broadcast extracts on its own thread); `bricks`/`bytes` is what was listed, `sent_bricks`/
// `sent_bytes` what was sent. splats_paint_delta: the delta (format version 2) of one add-blob
// stroke (12 dabs of radius 8, 2 vu apart along the equator) over the same sphere unpainted and
// painted all over: `bytes_unpainted`, `bytes_painted` and their `ratio` (issue 30: at most the
// colour's share of the point size, 12/8).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "bench.hpp"
#include "engine/level_set.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"
#include "engine/splats.hpp"
#include "protocol/cpp/little_endian.hpp"
#include "protocol/cpp/splats.hpp"
#include "engine/thread_pool.hpp"
#include "service/hub/broadcast.hpp"

namespace {

using namespace marzipan;
using namespace marzipan::bench;

MARZIPAN_BENCH("splats_full") {
  const double radius = opt.quick ? 30 : 100;
  const int side = opt.quick ? 80 : 256;
  const int reps = opt.quick ? 1 : 21;
  const double c = side / 2.0 - 0.3;
  const Volume vol = makeSphere({side, side, side}, {c, c + 0.2, c - 0.1}, radius);

  std::vector<int> threadCounts{1};
  if (opt.threads > 1) threadCounts.push_back(opt.threads);
  for (const int threads : threadCounts) {
    ThreadPool pool(threads);
    std::size_t points = 0, bytes = 0;
    std::vector<double> extractMs;
    const Timing t = measure(reps, [&] {
      const auto t0 = std::chrono::steady_clock::now();
      const auto bricks = extractAllSplats(vol, pool);
      extractMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      const auto encoded = encodeSplats(bricks);
      points = 0;
      for (const auto& b : bricks) points += b.points.size();
      bytes = encoded.size();
    });
    std::sort(extractMs.begin(), extractMs.end());
    emit("splats_full", threads, t,
         {{"radius", radius},
          {"side", side},
          {"extract_ms", extractMs[extractMs.size() / 2]},
          {"points", points},
          {"bytes", bytes},
          {"bytes_per_point", points ? double(bytes) / double(points) : 0.0}});
  }
}

MARZIPAN_BENCH("splats_delta") {
  const double radius = opt.quick ? 30 : 100;
  const int side = opt.quick ? 80 : 256;
  const int reps = opt.quick ? 5 : 201;
  const double c = side / 2.0;
  Volume vol = makeSphere({side, side, side}, {c, c, c}, radius);
  std::mt19937 rng{11};
  std::normal_distribution<double> gauss;
  Edit edit;
  service::HeldSplats held;
  held.delta(extractAllSplats(vol), vol);  // what a client that joined holds
  // The last application's results, read after the timing: the figures are not part of the work.
  std::vector<Int3> around;
  std::vector<BrickSplats> delta;
  std::vector<std::uint8_t> sent;
  const Timing t = measure(
      reps,
      [&] {
        const Vec3 dir = normalized({gauss(rng), gauss(rng), gauss(rng)});
        edit = addBlob(vol, BrushParams{Vec3{c, c, c} + dir * radius, 8, 1});
      },
      [&] {
        around = bricksAroundChanges(vol, edit.changes);
        delta = extractSplats(vol, around);
        sent = held.delta(delta, vol);
      });
  std::size_t points = 0;
  for (const auto& b : delta) points += b.points.size();
  const std::size_t bytes = encodedSplatsSize(delta), bricks = around.size(), sentBytes = sent.size(),
                    sentBricks = le::get32(sent.data() + 8);
  emit("splats_delta", 1, t,
       {{"radius", radius},
        {"side", side},
        {"dab_radius", 8},
        {"bricks", bricks},
        {"points", points},
        {"bytes", bytes},
        {"sent_bricks", sentBricks},
        {"sent_bytes", sentBytes}});
}

MARZIPAN_BENCH("splats_paint_delta") {
  const double radius = opt.quick ? 30 : 100;
  const int side = opt.quick ? 80 : 256;
  const int reps = opt.quick ? 1 : 5;
  const double c = side / 2.0;
  const Volume unpainted = makeSphere({side, side, side}, {c, c, c}, radius);
  Volume painted = unpainted;
  PaintSettings red;
  red.color = {200, 20, 10};
  red.radius = 1024;
  red.hardness = 0.99;
  paint(painted, red, {c, c, c});
  std::vector<StrokeDab> dabs;
  for (int i = 0; i < 12; ++i) {
    const double a = 2.0 * i / radius;
    dabs.emplace_back(Vec3{c + radius * std::cos(a), c + radius * std::sin(a), c});
  }
  std::size_t bytes[2] = {0, 0}, points = 0;
  const Timing t = measure(reps, [&] {
    for (int k = 0; k < 2; ++k) {
      Volume v = k ? painted : unpainted;
      const Edit e = applyStroke(v, StrokeSettings(Brush::AddBlob, 8, 1), dabs, {});
      const auto delta = extractSplats(v, bricksAroundChanges(v, e.changes));
      bytes[k] = encodeSplats(delta, kSplatFormatVersion).size();
      points = 0;
      for (const auto& b : delta) points += b.points.size();
    }
  });
  emit("splats_paint_delta", 1, t,
       {{"radius", radius},
        {"side", side},
        {"dab_radius", 8},
        {"dabs", dabs.size()},
        {"points", points},
        {"bytes_unpainted", bytes[0]},
        {"bytes_painted", bytes[1]},
        {"ratio", double(bytes[1]) / double(bytes[0])}});
}

}  // namespace
