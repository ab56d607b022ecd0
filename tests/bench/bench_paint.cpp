// Colour and mask (channels.hpp, paint.hpp): what painting costs, and what painted clay costs
// the geometry tools. On the radius-100 sphere in 256^3 (80^3, radius 30, with --quick), at the
// same random surface points, each dab on a fresh copy of the sphere (copies share bricks):
// - geometry_on_painted: an add-blob dab on clay painted all over, next to the same dab on the
//   unpainted sphere (target: at most 1.25x);
// - paint: a paint dab of the same radius next to the add-blob dab (target: at most 0.5x).
// paint_geometry: what channels cost the other geometry tools, painted over unpainted (the
// same sphere painted all over): a stroke of 16 add-blob dabs (radius 8, r/4 apart, target
// at most 1.25x), a CSG union of a sphere (radius 12) at a surface point with and without a
// colour, and one application of global smoothing (mean curvature flow).
#include <optional>
#include <random>
#include <vector>

#include "bench.hpp"
#include "engine/csg.hpp"
#include "engine/level_set.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"

namespace marzipan::bench {

namespace {

// The sphere both scenarios start from, unpainted and painted all over (a colour per voxel in
// every stored brick, no mask).
struct Spheres {
  Vec3 centre;
  double radius;
  Volume plain, painted;
};

Spheres spheres(const Options& opt, ThreadPool& pool) {
  const double half = opt.quick ? 40 : 128, radius = opt.quick ? 30 : 100;
  const Vec3 centre{half, half, half};
  Volume plain = makeSphere(opt.quick ? Int3{80, 80, 80} : Int3{256, 256, 256}, centre, radius);
  Volume painted = plain;
  PaintSettings all;
  all.color = {40, 90, 200};
  all.radius = 2 * radius;
  paint(painted, all, centre, pool);
  return {centre, radius, std::move(plain), std::move(painted)};
}

}  // namespace

MARZIPAN_BENCH("paint_dab") {
  ThreadPool pool(opt.threads);
  const Spheres sp = spheres(opt, pool);
  const int reps = opt.quick ? 5 : 101;
  for (const double r : opt.quick ? std::vector<double>{8} : std::vector<double>{8, 15}) {
    const auto timeDab = [&](const Volume& start, auto apply) {
      std::mt19937 rng{21};
      std::normal_distribution<double> gauss;
      Volume work = start;
      Vec3 at;
      return measure(
          reps,
          [&] {
            at = sp.centre + normalized({gauss(rng), gauss(rng), gauss(rng)}) * sp.radius;
            work = start;
          },
          [&] { apply(work, at); });
    };
    const auto addBlobDab = [&](Volume& v, Vec3 at) { addBlob(v, {at, r, 1}, pool); };
    timeDab(sp.plain, addBlobDab);  // warms the scratch and the copies' pages
    const Timing add = timeDab(sp.plain, addBlobDab);
    const Timing addPainted = timeDab(sp.painted, addBlobDab);
    PaintSettings st;
    st.color = {200, 30, 20};
    st.radius = r;
    const Timing paintDab = timeDab(sp.plain, [&](Volume& v, Vec3 at) { paint(v, st, at, pool); });
    // Under instructions.py the add-blob dab's own count comes along ("add_blob_instructions").
    const auto row = [&](const char* what, const Timing& t) {
      nlohmann::ordered_json extra{{"case", what}, {"radius", r}, {"add_blob_ms", add.median_ms},
                                   {"ratio_to_add_blob", t.median_ms / add.median_ms},
                                   {"cpu_ratio_to_add_blob", t.cpu_median_ms / add.cpu_median_ms}};
      if (add.measurement) extra["add_blob_measurement"] = add.measurement;
      emit("paint_dab", opt.threads, t, std::move(extra));
    };
    row("add_blob_on_painted", addPainted);
    row("paint", paintDab);
  }
}

MARZIPAN_BENCH("paint_geometry") {
  ThreadPool pool(opt.threads);
  const Spheres sp = spheres(opt, pool);
  // Each call on a fresh copy, at the same random surface points for both volumes.
  const auto time = [&](const Volume& start, int reps, auto apply) {
    std::mt19937 rng{33};
    std::normal_distribution<double> gauss;
    Volume work = start;
    Vec3 dir;
    return measure(
        reps,
        [&] {
          dir = normalized({gauss(rng), gauss(rng), gauss(rng)});
          work = start;
        },
        [&] { apply(work, dir); });
  };
  const auto row = [&](const char* what, const Timing& onPlain, const Timing& t, nlohmann::ordered_json extra) {
    extra["case"] = what;
    extra["unpainted_ms"] = onPlain.median_ms;
    extra["ratio_to_unpainted"] = t.median_ms / onPlain.median_ms;
    extra["cpu_ratio_to_unpainted"] = t.cpu_median_ms / onPlain.cpu_median_ms;
    if (onPlain.measurement) extra["unpainted_measurement"] = onPlain.measurement;
    emit("paint_geometry", opt.threads, t, std::move(extra));
  };
  const int reps = opt.quick ? 5 : 51;
  constexpr double r = 8;
  const auto stroke = [&](Volume& v, Vec3 dir) {
    const Vec3 along = normalized(cross(dir, Vec3{0.3, 0.5, 0.8}));
    std::vector<StrokeDab> dabs;
    for (int i = 0; i < 16; ++i) dabs.push_back({sp.centre + dir * sp.radius + along * (r / 4 * (i - 7.5)), 1.0, dir});
    applyStroke(v, {Brush::AddBlob, r, 1}, dabs, {}, pool);
  };
  time(sp.plain, reps, stroke);  // warms the scratch and the copies' pages
  row("stroke16", time(sp.plain, reps, stroke), time(sp.painted, reps, stroke), {{"radius", r}, {"dabs", 16}});
  const auto csg = [&](std::optional<Rgb8> color) {
    return [&, color](Volume& v, Vec3 dir) {
      CsgParams p;
      p.center = sp.centre + dir * sp.radius;
      p.radius = 12;
      applyCsg(v, p, pool, color);
    };
  };
  time(sp.plain, reps, csg(std::nullopt));  // the same warm-up for the CSG tool's own scratch
  const Timing csgPlain = time(sp.plain, reps, csg(std::nullopt));
  row("csg_add", csgPlain, time(sp.painted, reps, csg(std::nullopt)), {{"radius", 12}});
  row("csg_add_color_unpainted", csgPlain, time(sp.plain, reps, csg(Rgb8{200, 30, 20})), {{"radius", 12}});
  row("csg_add_color", csgPlain, time(sp.painted, reps, csg(Rgb8{200, 30, 20})), {{"radius", 12}});
  const auto smoothAll = [&](Volume& v, Vec3) { meanCurvatureFlow(v, 1, 1, pool); };
  const int globalReps = opt.quick ? 3 : 7;
  time(sp.plain, 1, smoothAll);
  row("global_smooth", time(sp.plain, globalReps, smoothAll), time(sp.painted, globalReps, smoothAll), {{"iterations", 1}});
}

}  // namespace marzipan::bench
