// Warp scenarios (engine/level_set.hpp, warps): a grab message on the 256^3 sphere at two drag lengths, the
// same message through the service (a Session's warp stroke), and a snake hook move and a pinch path
// move beside an add-blob dab of the same radius.
#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include "bench.hpp"
#include "engine/level_set.hpp"
#include "engine/solids.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"

namespace marzipan::bench {

namespace {

struct WarpSphere {
  Int3 dims;
  Vec3 centre;
  double radius;
};

WarpSphere warpSphere(const Options& opt) {
  return opt.quick ? WarpSphere{{96, 96, 96}, {48, 48, 48}, 30} : WarpSphere{{256, 256, 256}, {128, 128, 128}, 100};
}

Vec3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> gauss;
  return normalized({gauss(rng), gauss(rng), gauss(rng)});
}

}  // namespace

// One grab message of a stroke under way: the volume already holds the stroke's previous
// message (the pointer 90% as far along), and this one moves the anchor (a random point of the
// sphere) `pointer` vu in a random direction, from the stroke's base. Radius 20; the targets are
// <= 8 ms at 20 vu and <= 25 ms at 60 vu on 2 threads (issue 29 §5).
MARZIPAN_BENCH("grab") {
  const WarpSphere s = warpSphere(opt);
  ThreadPool pool(opt.threads);
  const Volume base = makeSphere(s.dims, s.centre, s.radius);
  std::mt19937 rng{7};
  const double r = 20;
  for (const double pointer : opt.quick ? std::vector<double>{10} : std::vector<double>{20, 60}) {
    Volume v = base;
    Vec3 anchor, d;
    const Timing t = measure(
        opt.quick ? 3 : 31,
        [&] {
          anchor = s.centre + randomUnit(rng) * s.radius;
          d = randomUnit(rng) * pointer;
          v = base;
          grab(v, base, anchor, d * 0.9, r, pool);
        },
        [&] { grab(v, base, anchor, d, r, pool); });
    emit("grab", opt.threads, t, {{"radius", r}, {"pointer_vu", pointer}});
  }
}

// The grab message of "grab" as the hub applies it: Session::strokeDabs of a warp stroke (PROTOCOL.md,
// warp strokes) whose previous message put the pointer 90% as far, the message the pointer's point
// alone: the engine's grab of the stroke's base, the fold into its history step, the digest and
// the bricks to send. Also the cost estimate of the message (apply_op.hpp, warpStrokeCost) and
// the voxels per second it implies, which the other tools' estimates run at (2.2-3.3e7 quiet).
MARZIPAN_BENCH("grab_message") {
  const WarpSphere s = warpSphere(opt);
  ThreadPool pool(opt.threads);
  const Volume base = makeSphere(s.dims, s.centre, s.radius);
  std::mt19937 rng{7};
  service::WarpStroke w;
  w.radius = 20;
  for (const double pointer : opt.quick ? std::vector<double>{10} : std::vector<double>{20, 60}) {
    std::optional<service::Session> session;
    service::StrokeId id = 0;
    Vec3 anchor, d;
    const Timing t = measure(
        opt.quick ? 3 : 31,
        [&] {
          anchor = s.centre + randomUnit(rng) * s.radius;
          d = randomUnit(rng) * pointer;
          session.emplace(base);
          id = session->beginWarp(w);
          session->strokeDabs(id, {service::Dab{anchor}, service::Dab{anchor + d * 0.9}}, pool);
        },
        [&] { session->strokeDabs(id, {service::Dab{anchor + d}}, pool); });
    const std::vector<Vec3> last{anchor + d};
    const double estimate = service::warpStrokeCost(base, w, anchor, last).voxels;
    emit("grab_message", opt.threads, t,
         {{"radius", w.radius}, {"pointer_vu", pointer}, {"estimate_voxels", estimate},
          {"voxels_per_s", estimate / (t.median_ms / 1000)}});
  }
}

namespace {

// Scenarios `name`: a path-dependent warp's move against an add-blob dab of the same radius (8),
// each `reps` times at random points of the sphere, a move and a dab in turn (measurePair):
// draw(rng, s, i) picks the i-th move of the run (the runs start from the sphere), apply(v,
// pool) makes it. Untimed, as many moves and dabs as timed run first, on copies freed before
// the timing, so that the changed bricks' memory is recycled for both: without it, when the
// moves were timed before the dabs (until measurePair), the moves grew the heap and paid the
// first touch of their new bricks' pages, and the dabs after them reused the freed moves'
// memory (one thread, the snake hook read 2.7-3.1x the dab timed first and 1.5x timed after
// it; 2026-11-29, load ~6); timed in turn, each would still pay its own first touches.
// `ratio_to_dab` is the ratio of the medians, `pair_ratio_to_dab` the median of a move's time
// over the next dab's.
template <class Draw, class Apply>
void moveAgainstDab(const Options& opt, const char* name, unsigned seed, Draw draw, Apply apply) {
  const WarpSphere s = warpSphere(opt);
  ThreadPool pool(opt.threads);
  const Volume sphere = makeSphere(s.dims, s.centre, s.radius);
  const double r = 8;
  const int reps = opt.quick ? 5 : 101;
  {
    std::mt19937 other{seed + 1};
    Volume warm = sphere, dabbed = sphere;
    for (int i = 0; i < reps; ++i) {
      draw(other, s, i);
      apply(warm, r, pool);
      addBlob(dabbed, BrushParams{s.centre + randomUnit(other) * s.radius, r, 1}, pool);
    }
  }
  // The moves and the dabs in turn (measurePair): each its own volume, and the dabs their own
  // points (before 2026-11-30 20:05 UTC the dabs followed the moves, on the moves' generator).
  std::mt19937 rng{seed}, dabRng{seed + 2};
  Volume moved = sphere, dabbed = sphere;
  int i = 0;
  BrushParams p{{}, r, 1};
  double pairRatio = 0;
  const auto [move, dab] = measurePair(
      reps, [&] { draw(rng, s, i++); }, [&] { apply(moved, r, pool); },
      [&] { p.center = s.centre + randomUnit(dabRng) * s.radius; }, [&] { addBlob(dabbed, p, pool); }, &pairRatio);
  nlohmann::ordered_json extra{
      {"radius", r}, {"move_vu", 2}, {"add_blob_dab_ms", dab.median_ms}, {"ratio_to_dab", move.median_ms / dab.median_ms}};
  if (dab.measurement) extra["dab_measurement"] = dab.measurement;
  if (pairRatio > 0) extra["pair_ratio_to_dab"] = pairRatio;
  emit(name, opt.threads, move, extra);
}

}  // namespace

// A snake hook move of 2 vu from a random point of the sphere, roughly outwards: the target is
// <= 2x the dab.
MARZIPAN_BENCH("snake_hook") {
  Vec3 anchor, step;
  moveAgainstDab(
      opt, "snake_hook", 9,
      [&](std::mt19937& rng, const WarpSphere& s, int) {
        const Vec3 n = randomUnit(rng);
        anchor = s.centre + n * s.radius;
        step = normalized(n + randomUnit(rng) * 0.5) * 2.0;
      },
      [&](Volume& v, double r, ThreadPool& pool) { snakeHook(v, anchor, anchor + step, r, pool); });
}

// The moves of tentacles being pulled, every one timed: a snake hook stroke of 30 moves of 2 vu
// (60 vu) from a random point of the sphere on one of its diagonals (the 256^3 grid holds the
// tentacle there), slanting a little, then the next from another point. "snake_hook" times a
// move off the sphere, which a stroke makes once: its later moves, along the tentacle with the
// plateau's ball sunk into the tip, the tip's foot points and (while it is young) the wider
// support, cost more, and instructions.py's mean over these moves is the stroke's.
MARZIPAN_BENCH("snake_hook_tentacle") {
  constexpr int kTentacleMoves = 30;
  Vec3 anchor, step;
  moveAgainstDab(
      opt, "snake_hook_tentacle", 13,
      [&](std::mt19937& rng, const WarpSphere& s, int i) {
        if (i % kTentacleMoves == 0) {
          std::uniform_int_distribution<int> sign(0, 1);
          const Vec3 n = normalized(Vec3{sign(rng) ? 1.0 : -1.0, sign(rng) ? 1.0 : -1.0, sign(rng) ? 1.0 : -1.0});
          anchor = s.centre + n * s.radius;
          step = normalized(n + randomUnit(rng) * 0.15) * 2.0;
        } else {
          anchor = anchor + step;
        }
      },
      [&](Volume& v, double r, ThreadPool& pool) { snakeHook(v, anchor, anchor + step, r, pool); });
}

// A pinch path move (pinchAlong) of 2 vu along the sphere's surface from a random point, amount
// 1 (the browser's dabs are a quarter radius apart).
MARZIPAN_BENCH("pinch_path") {
  Vec3 from, to, n;
  moveAgainstDab(
      opt, "pinch_path", 11,
      [&](std::mt19937& rng, const WarpSphere& s, int) {
        n = randomUnit(rng);
        from = s.centre + n * s.radius;
        to = from + normalized(cross(n, randomUnit(rng))) * 2.0;
      },
      [&](Volume& v, double r, ThreadPool& pool) { pinchAlong(v, from, to, n, 1, r, pool); });
}

}  // namespace marzipan::bench
