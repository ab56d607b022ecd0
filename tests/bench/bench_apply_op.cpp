// The cost estimate of a stroke message (server/service/apply_op.hpp, strokeDabVoxels) against
// what the message costs: one add-blob dab of radius 12 on the 96^3 sphere, alone and over 4096
// weak remembered dabs lying where it lands (the case of tests/service/test_apply_op.cpp, which
// checks the estimate's ratio against the range this measures). Prints both ratios.
#include <vector>

#include "bench.hpp"
#include "engine/level_set.hpp"
#include "engine/solids.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"

namespace marzipan::bench {

MARZIPAN_BENCH("stroke_memory_scan") {
  ThreadPool pool(opt.threads);
  const Volume sphere = makeSolid(SolidKind::Sphere, {96, 96, 96});
  const StrokeSettings st{Brush::AddBlob, 12, 1};
  const Vec3 at{47.5 + 0.35 * 96, 47.5, 47.5};
  std::vector<StrokeDab> memory;
  for (int i = 0; i < int(service::Session::kMaxStrokeMemory); ++i)
    memory.push_back({{at.x, at.y + (i % 16) * 0.25, at.z + (i / 16 % 16) * 0.25}, 0.02});
  const std::vector<StrokeDab> dab{{at, 1}};
  const int reps = opt.quick ? 1 : 9;
  Volume v = sphere;
  const auto reset = [&] { v = sphere; };
  const Timing alone = measure(reps, reset, [&] { applyStroke(v, st, dab, {}, pool); });
  const Timing scanning = measure(reps, reset, [&] { applyStroke(v, st, dab, memory, pool); });
  const double plain = service::strokeDabVoxels(sphere, st.radius, 1, 1, {});
  const double estimate = service::strokeDabVoxels(sphere, st.radius, 1, 1, memory);
  emit("stroke_memory_scan", opt.threads, scanning,
       {{"radius", st.radius}, {"remembered", memory.size()}, {"alone_median_ms", alone.median_ms},
        {"time_ratio", scanning.median_ms / alone.median_ms},
        {"cpu_time_ratio", scanning.cpu_median_ms / alone.cpu_median_ms}, {"estimate_ratio", estimate / plain}});
}

}  // namespace marzipan::bench
