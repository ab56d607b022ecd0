// Level-set scenarios: Table 7.2 of Bærentzen's thesis (docs/method.md) (add blob and smoothing on ROIs of side
// 10..70, and 100, 150, on the surface of a radius-100 sphere), one whole-volume curvature
// iteration and dilation, and the memory the volume takes.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <random>

#include "bench.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"

namespace marzipan::bench {

namespace {

// The thesis's seconds per application (Athlon, 2001), by ROI side.
struct SeedRow {
  int side;
  double addBlobMs, smoothMs;
};
constexpr SeedRow kSeed[] = {{10, 44, 47},   {20, 134, 153},  {30, 307, 352},  {40, 703, 878},
                             {50, 973, 1109}, {60, 1246, 1293}, {70, 1744, 1453}};

struct Sphere {
  Int3 dims;
  Vec3 centre;
  double radius;
};
Sphere benchSphere(const Options& opt) {
  return opt.quick ? Sphere{{80, 80, 80}, {40, 40, 40}, 30} : Sphere{{256, 256, 256}, {128, 128, 128}, 100};
}

std::size_t bandVoxelsIn(const Volume& v, const Box& box) {
  const Box b = box.intersect(v.domain());
  std::vector<float> d(std::size_t(b.voxels()));
  v.gather(b, d.data());
  std::size_t n = 0;
  for (float x : d) n += std::fabs(x) < v.band() ? 1 : 0;
  return n;
}

void table72(const Options& opt, const char* scenario, bool addBlobTool) {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  const std::vector<int> sides = opt.quick ? std::vector<int>{10, 30} : std::vector<int>{10, 20, 30, 40, 50, 60, 70, 100, 150};
  for (int side : sides) {
    Volume v = makeSphere(s.dims, s.centre, s.radius);
    std::mt19937 rng{unsigned(side)};
    std::normal_distribution<double> gauss;
    const int reps = opt.quick ? 3 : (side <= 70 ? 21 : 7);
    std::size_t band = 0;
    BrushParams p;
    p.radius = side / 2.0;
    p.strength = 1;
    const Timing t = measure(
        reps,
        [&] {
          // A random point of the surface; the surface there moves with the tools, which is
          // what the thesis's random applications did too.
          const Vec3 dir = normalized({gauss(rng), gauss(rng), gauss(rng)});
          p.center = s.centre + dir * s.radius;
          band = bandVoxelsIn(v, boxAround(p.center, {p.radius, p.radius, p.radius}));
        },
        [&] {
          if (addBlobTool) {
            addBlob(v, p, pool);
          } else {
            smooth(v, p, pool);
          }
        });
    nlohmann::ordered_json extra;
    extra["roi"] = side;
    extra["band_voxels"] = band;
    for (const auto& row : kSeed)
      if (row.side == side) {
        const double seed = addBlobTool ? row.addBlobMs : row.smoothMs;
        extra["seed_ms"] = seed;
        extra["speedup_vs_seed"] = seed / t.median_ms;
      }
    emit(scenario, opt.threads, t, extra);
  }
}

}  // namespace

MARZIPAN_BENCH("table72_add_blob") { table72(opt, "table72_add_blob", true); }
MARZIPAN_BENCH("table72_smooth") { table72(opt, "table72_smooth", false); }

// The thread target of Table 7.2's largest ROI (70^3, add blob and smoothing): the same
// applications on a pool of one thread and of `--threads` (2 when not given), in alternation so
// that both see the same load, reported with the ratio of their medians (target >= 1.6).
MARZIPAN_BENCH("table72_threads") {
  const Sphere s = benchSphere(opt);
  const int threads = opt.threads > 1 ? opt.threads : 2;
  ThreadPool one(1), many(threads);
  const int side = opt.quick ? 30 : 70;
  for (const bool addBlobTool : {true, false}) {
    Volume v = makeSphere(s.dims, s.centre, s.radius);
    std::mt19937 rng{unsigned(side)};
    std::normal_distribution<double> gauss;
    BrushParams p;
    p.radius = side / 2.0;
    p.strength = 1;
    std::vector<double> ms[2], cpu[2];
    for (int rep = 0; rep < (opt.quick ? 4 : 42); ++rep) {
      p.center = s.centre + normalized({gauss(rng), gauss(rng), gauss(rng)}) * s.radius;
      ThreadPool& pool = rep % 2 == 0 ? one : many;
      const double c0 = processCpuMs();
      const auto t0 = std::chrono::steady_clock::now();
      if (addBlobTool) {
        addBlob(v, p, pool);
      } else {
        smooth(v, p, pool);
      }
      ms[rep % 2].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      cpu[rep % 2].push_back(processCpuMs() - c0);
    }
    for (int k = 0; k < 2; ++k) {
      std::sort(ms[k].begin(), ms[k].end());
      std::sort(cpu[k].begin(), cpu[k].end());
    }
    const double oneMs = ms[0][ms[0].size() / 2], manyMs = ms[1][ms[1].size() / 2];
    Timing t;
    t.median_ms = manyMs;
    t.min_ms = ms[1].front();
    t.max_ms = ms[1].back();
    t.reps = int(ms[1].size());
    t.cpu_median_ms = cpu[1][cpu[1].size() / 2];
    emit("table72_threads", threads, t,
         {{"tool", addBlobTool ? "add_blob" : "smooth"}, {"roi", side}, {"one_thread_ms", oneMs},
          {"one_thread_cpu_ms", cpu[0][cpu[0].size() / 2]},
          {"speedup", oneMs / manyMs}});
  }
}

// Dabs at random points of the sphere (add blob, strength 1), by radius: the cost should grow
// with the band under the dab (r^2), not with its box (r^3).
MARZIPAN_BENCH("dab") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  std::mt19937 rng{5};
  std::normal_distribution<double> gauss;
  for (const double r : opt.quick ? std::vector<double>{8} : std::vector<double>{5, 8, 10, 15, 35}) {
    BrushParams p{{}, r, 1};
    const Timing t = measure(
        opt.quick ? 5 : 101, [&] { p.center = s.centre + normalized({gauss(rng), gauss(rng), gauss(rng)}) * s.radius; },
        [&] { addBlob(v, p, pool); });
    emit("dab", opt.threads, t, {{"radius", r}});
  }
}

// The surface tools' dabs (level_set.hpp, Brush) at random points of the sphere, next to an
// add-blob dab of the same radius at the same points (the target: within 2x). A row per tool:
// inflate with a height of 1 vu (one sub-step, the distance an add-blob dab at strength 1 moves)
// and of 4 vu (next to clay, add blob along the dab's normal, at the same height); flatten, with
// the time of fitting its plane at a stroke's start; crease.
MARZIPAN_BENCH("surface_dab") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  const int reps = opt.quick ? 5 : 101;
  for (const double r : opt.quick ? std::vector<double>{8} : std::vector<double>{8, 15}) {
    // Each tool at the same sequence of points, on a fresh copy of the sphere each time (the
    // copy shares its bricks: only the ones a dab writes are copied, outside the timing).
    // Flatten's plane is fitted once per stroke, at its start (outside the timing; its own
    // time is a figure of the flatten row).
    const auto timeTool = [&](StrokeSettings st, bool withNormal) {
      std::mt19937 rng{11};
      std::normal_distribution<double> gauss;
      Volume work = v;
      StrokeDab dab;
      const bool planar = brushUsesPlane(st.tool);
      return measure(
          reps,
          [&] {
            const Vec3 n = normalized({gauss(rng), gauss(rng), gauss(rng)});
            dab = {s.centre + n * s.radius, 1.0, withNormal ? n : Vec3{}};
            work = v;
            if (planar) st.plane = fitBrushPlane(v, dab.center, r);
          },
          [&] { applyStroke(work, st, {&dab, 1}, {}, pool); });
    };
    timeTool({Brush::AddBlob, r, 1}, false);  // warms the scratch and the copies' pages: the first tool timed read up to 2x
    const Timing add = timeTool({Brush::AddBlob, r, 1}, false);
    const auto row = [&](const char* tool, const Timing& t, const Timing& base, const char* baseName,
                         nlohmann::ordered_json extra) {
      extra["tool"] = tool;
      extra["radius"] = r;
      extra[std::string(baseName) + "_ms"] = base.median_ms;
      extra[std::string("ratio_to_") + baseName] = t.median_ms / base.median_ms;
      extra[std::string("cpu_ratio_to_") + baseName] = t.cpu_median_ms / base.cpu_median_ms;
      emit("surface_dab", opt.threads, t, std::move(extra));
    };
    row("inflate", timeTool({Brush::Inflate, r, 1, 1.0}, false), add, "add_blob", {{"height", 1}});
    const Timing clay4 = timeTool({Brush::Clay, r, 1, 4.0}, true);
    row("inflate", timeTool({Brush::Inflate, r, 1, 4.0}, false), clay4, "clay", {{"height", 4}});
    std::mt19937 rng{12};
    std::normal_distribution<double> gauss;
    const Timing fit = measure(reps, [&] {
      fitBrushPlane(v, s.centre + normalized({gauss(rng), gauss(rng), gauss(rng)}) * s.radius, r);
    });
    row("flatten", timeTool({Brush::Flatten, r, 1}, false), add, "add_blob", {{"fit_plane_ms", fit.median_ms}});
    row("crease", timeTool({Brush::Crease, r, 1}, false), add, "add_blob", {});
  }
}

// n dabs r/4 apart along a random line through a random point of the sphere, each carrying the
// sphere's normal there (the starting normal a stroke with a height reads; others ignore it).
class DabLine {
 public:
  DabLine(const Sphere& s, double r, unsigned seed) : s_(s), r_(r), rng_(seed) {}
  void place(std::vector<StrokeDab>& dabs, int n) {
    const Vec3 dir = normalized({gauss_(rng_), gauss_(rng_), gauss_(rng_)});
    const Vec3 along = normalized(cross(dir, normalized({gauss_(rng_), gauss_(rng_), gauss_(rng_)})));
    dabs.clear();
    for (int i = 0; i < n; ++i) dabs.push_back({s_.centre + dir * s_.radius + along * (r_ / 4 * (i - (n - 1) / 2.0)), 1.0, dir});
  }

 private:
  Sphere s_;
  double r_;
  std::mt19937 rng_;
  std::normal_distribution<double> gauss_;
};

// One stroke.dabs message of 16 dabs r/4 apart along a line on the sphere (one application of
// the swept brush), next to a single dab of the same radius: the target is <= 2x.
MARZIPAN_BENCH("stroke16") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  constexpr double r = 8;
  const StrokeSettings st{Brush::AddBlob, r, 1};
  DabLine line(s, r, 6);
  std::vector<StrokeDab> dabs;
  const int reps = opt.quick ? 5 : 101;
  const Timing one = measure(reps, [&] { line.place(dabs, 1); }, [&] { applyStroke(v, st, dabs, {}, pool); });
  const Timing sixteen = measure(reps, [&] { line.place(dabs, 16); }, [&] { applyStroke(v, st, dabs, {}, pool); });
  nlohmann::ordered_json extra{{"radius", r}, {"dabs", 16}, {"one_dab_ms", one.median_ms},
                               {"ratio_to_one_dab", sixteen.median_ms / one.median_ms}, {"one_dab_cpu_ms", one.cpu_median_ms},
                               {"cpu_ratio_to_one_dab", sixteen.cpu_median_ms / one.cpu_median_ms}};
  if (one.measurement) extra["one_dab_measurement"] = one.measurement;
  emit("stroke16", opt.threads, sixteen, std::move(extra));
}

// The same message of 16 dabs (radius 8) in a stroke with a height of 4 vu (strength 1 in the
// web client): four sub-steps of evolve and redistance, so about four times stroke16.
MARZIPAN_BENCH("stroke16_height4") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  constexpr double r = 8;
  const StrokeSettings plain{Brush::AddBlob, r, 1}, tall{Brush::AddBlob, r, 1, 4.0};
  DabLine line(s, r, 7);
  std::vector<StrokeDab> dabs;
  const auto place = [&] { line.place(dabs, 16); };
  const int reps = opt.quick ? 5 : 51;
  const Timing one = measure(reps, place, [&] { applyStroke(v, plain, dabs, {}, pool); });
  const Timing four = measure(reps, place, [&] { applyStroke(v, tall, dabs, {}, pool); });
  emit("stroke16_height4", opt.threads, four,
       {{"radius", r}, {"dabs", 16}, {"height", 4}, {"no_height_ms", one.median_ms},
        {"ratio_to_no_height", four.median_ms / one.median_ms}});
}

namespace {

// Dab i of a drag along the great circle of the sphere from dir towards along, `spacing` vu apart.
StrokeDab dragDab(const Sphere& s, Vec3 dir, Vec3 along, double spacing, int i) {
  const double angle = spacing * i / s.radius;
  const Vec3 n = normalized(dir * std::cos(angle) + along * std::sin(angle));
  return {s.centre + n * s.radius, 1.0, n};
}

// The median over strokes of each stroke's median message (wall and CPU), with the range of
// the wall ones.
Timing acrossStrokes(std::vector<double> ms, std::vector<double> cpu, int reps) {
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  Timing t;
  t.median_ms = ms[ms.size() / 2];
  t.min_ms = ms.front();
  t.max_ms = ms.back();
  t.reps = reps;
  t.cpu_median_ms = cpu[cpu.size() / 2];
  return t;
}

}  // namespace

// A stroke dragged as the web client sends it (tests/load/marzipan_load.py's web-client mode): a
// dab per 60 Hz pointer event, 0.63 vu apart along a great circle of the sphere, merged into
// messages of 12, radius 7; each message carries the stroke's memory of the dabs it applied
// before (up to 60 here, as the server keeps them). Without a height, and with the height the
// web client asks for at strength 0.5 (radius / 4). Every message of every stroke is timed.
MARZIPAN_BENCH("stroke_drag") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  constexpr double r = 7, spacing = 0.63;
  constexpr int perMessage = 12, messages = 6;
  const int strokes = opt.quick ? 1 : 12;
  std::mt19937 rng{8};
  std::normal_distribution<double> gauss;
  for (const double height : {0.0, r / 4}) {
    Volume v = makeSphere(s.dims, s.centre, s.radius);
    const StrokeSettings st = height == 0 ? StrokeSettings{Brush::AddBlob, r, 1}
                                          : StrokeSettings{Brush::AddBlob, r, 1, height};
    std::vector<double> ms, cpu;
    for (int k = 0; k < strokes; ++k) {
      const Vec3 dir = normalized({gauss(rng), gauss(rng), gauss(rng)});
      const Vec3 along = normalized(cross(dir, normalized({gauss(rng), gauss(rng), gauss(rng)})));
      std::vector<StrokeDab> memory, dabs;
      int placed = 0;
      const Timing t = measure(
          messages,
          [&] {
            memory.insert(memory.end(), dabs.begin(), dabs.end());
            dabs.clear();
            for (int i = 0; i < perMessage; ++i, ++placed) dabs.push_back(dragDab(s, dir, along, spacing, placed));
          },
          [&] { applyStroke(v, st, dabs, memory, pool); });
      ms.push_back(t.median_ms);
      cpu.push_back(t.cpu_median_ms);
    }
    const Timing t = acrossStrokes(ms, cpu, strokes * messages);
    emit("stroke_drag", opt.threads, t,
         {{"radius", r}, {"height", height}, {"dabs_per_message", perMessage}, {"messages_per_stroke", messages},
          {"spacing", spacing}, {"ms_per_dab", t.median_ms / perMessage}, {"cpu_ms_per_dab", t.cpu_median_ms / perMessage}});
  }
}

// The same drag (no height), then the pointer drawn back over the same path within the stroke,
// as a sculptor scrubs: the messages back add nothing the stroke's memory does not hold. Timed:
// the messages back, per message.
MARZIPAN_BENCH("stroke_scrub") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  constexpr double r = 7, spacing = 0.63;
  constexpr int perMessage = 12, messages = 6;
  const int strokes = opt.quick ? 1 : 12;
  std::mt19937 rng{9};
  std::normal_distribution<double> gauss;
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  const StrokeSettings st{Brush::AddBlob, r, 1};
  std::vector<double> ms, cpu;
  for (int k = 0; k < strokes; ++k) {
    const Vec3 dir = normalized({gauss(rng), gauss(rng), gauss(rng)});
    const Vec3 along = normalized(cross(dir, normalized({gauss(rng), gauss(rng), gauss(rng)})));
    std::vector<StrokeDab> path, memory;
    for (int i = 0; i < perMessage * messages; ++i) path.push_back(dragDab(s, dir, along, spacing, i));
    for (int m = 0; m < messages; ++m) {
      const std::span<const StrokeDab> forth(path.data() + m * perMessage, perMessage);
      applyStroke(v, st, forth, memory, pool);
      memory.insert(memory.end(), forth.begin(), forth.end());
    }
    std::vector<StrokeDab> back(path.rbegin(), path.rend());
    int m = 0;
    const Timing t = measure(
        messages, [] {},
        [&] {
          applyStroke(v, st, std::span<const StrokeDab>(back.data() + m * perMessage, perMessage), memory, pool);
          ++m;
        });
    ms.push_back(t.median_ms);
    cpu.push_back(t.cpu_median_ms);
  }
  emit("stroke_scrub", opt.threads, acrossStrokes(ms, cpu, strokes * messages),
       {{"radius", r}, {"dabs_per_message", perMessage}, {"messages_back", messages}, {"spacing", spacing}});
}

MARZIPAN_BENCH("mcf_global") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  const Timing t = measure(opt.quick ? 1 : 5, [&] { meanCurvatureFlow(v, 1, 1.0, pool); });
  emit("mcf_global", opt.threads, t, {{"radius", s.radius}, {"openvdb_ms", 1065}});
}

MARZIPAN_BENCH("dilate_global") {
  const Sphere s = benchSphere(opt);
  ThreadPool pool(opt.threads);
  Volume v = makeSphere(s.dims, s.centre, s.radius);
  const Timing t = measure(
      opt.quick ? 1 : 5, [&] { v = makeSphere(s.dims, s.centre, s.radius); }, [&] { dilate(v, 1, pool); });
  emit("dilate_global", opt.threads, t,
       {{"radius", s.radius}, {"radius_after", std::cbrt(3 * insideVolume(v) / (4 * std::numbers::pi))},
        {"openvdb_ms", 2000}});
}

MARZIPAN_BENCH("memory") {
  struct Case {
    int n;
    double r;
  };
  const std::vector<Case> cases = opt.quick ? std::vector<Case>{{128, 50}} : std::vector<Case>{{256, 100}, {512, 200}};
  for (const auto& c : cases) {
    Volume v({c.n, c.n, c.n});
    const double h = (c.n - 1) / 2.0;
    const Timing t = measure(1, [&] { v = makeSphere({c.n, c.n, c.n}, {h, h, h}, c.r); });
    const std::size_t band = bandVoxelsIn(v, v.domain());
    // Painted all over: every stored brick carries channels (channels.hpp), a colour per voxel.
    Volume painted = v;
    std::vector<BrickChange> paint;
    painted.forEachPresentBrick([&](Int3 b, const Brick&) {
      auto bp = std::make_shared<BrickPaint>();
      for (int i = 0; i < kBrickVoxels; ++i) bp->t[i] = {std::uint8_t(i), 90, 200, 0};
      BrickRef now = painted.brick(b);
      now.paint = painted.canonicalPaint(std::move(bp));
      paint.push_back({b, painted.brick(b), std::move(now)});
    });
    painted.publish(paint, true);
    emit("memory", opt.threads, t,
         {{"size", c.n}, {"radius", c.r}, {"bytes", v.memoryBytes()}, {"bricks", v.presentBricks()},
          {"band_voxels", band}, {"bytes_per_band_voxel", double(v.memoryBytes()) / double(band)},
          {"painted_bytes", painted.memoryBytes()}, {"painted_bricks", painted.paintedBricks()},
          {"openvdb_bytes", c.n == 256 ? 10.55e6 : 0.0}});
  }
}

}  // namespace marzipan::bench
