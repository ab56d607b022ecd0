// Colour and mask (channels.hpp, paint.hpp): what painting costs, and what painted clay costs
// the geometry tools. On the radius-100 sphere in 256^3 (80^3, radius 30, with --quick), at the
// same random surface points, each dab on a fresh copy of the sphere (copies share bricks):
// - geometry_on_painted: an add-blob dab on clay painted all over, next to the same dab on the
//   unpainted sphere (target: at most 1.25x);
// - paint: a paint dab of the same radius next to the add-blob dab (target: at most 0.5x).
#include <random>

#include "bench.hpp"
#include "engine/level_set.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"

namespace marzipan::bench {

MARZIPAN_BENCH("paint_dab") {
  const Int3 dims = opt.quick ? Int3{80, 80, 80} : Int3{256, 256, 256};
  const double half = opt.quick ? 40 : 128, radius = opt.quick ? 30 : 100;
  const Vec3 centre{half, half, half};
  ThreadPool pool(opt.threads);
  const Volume plain = makeSphere(dims, centre, radius);
  // Painted all over: a colour per voxel in every stored brick, no mask.
  Volume painted = plain;
  {
    PaintSettings all;
    all.color = {40, 90, 200};
    all.radius = 2 * radius;
    paint(painted, all, centre, pool);
  }
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
            at = centre + normalized({gauss(rng), gauss(rng), gauss(rng)}) * radius;
            work = start;
          },
          [&] { apply(work, at); });
    };
    const auto addBlobDab = [&](Volume& v, Vec3 at) { addBlob(v, {at, r, 1}, pool); };
    timeDab(plain, addBlobDab);  // warms the scratch and the copies' pages
    const Timing add = timeDab(plain, addBlobDab);
    const Timing addPainted = timeDab(painted, addBlobDab);
    PaintSettings st;
    st.color = {200, 30, 20};
    st.radius = r;
    const Timing paintDab = timeDab(plain, [&](Volume& v, Vec3 at) { paint(v, st, at, pool); });
    emit("paint_dab", opt.threads, addPainted,
         {{"case", "add_blob_on_painted"}, {"radius", r}, {"add_blob_ms", add.median_ms},
          {"ratio_to_add_blob", addPainted.median_ms / add.median_ms},
          {"cpu_ratio_to_add_blob", addPainted.cpu_median_ms / add.cpu_median_ms}});
    emit("paint_dab", opt.threads, paintDab,
         {{"case", "paint"}, {"radius", r}, {"add_blob_ms", add.median_ms},
          {"ratio_to_add_blob", paintDab.median_ms / add.median_ms},
          {"cpu_ratio_to_add_blob", paintDab.cpu_median_ms / add.cpu_median_ms}});
  }
}

}  // namespace marzipan::bench
