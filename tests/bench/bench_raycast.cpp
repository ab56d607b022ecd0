// Ray-cast frames: a lit 512x512 view of a radius-100 sphere in 256^3 from a 3/4 view, JPEG
// (quality 75) included, as the viewer requests it. median_ms is the frame streamed while a
// client edits or orbits (a Preview, render_ms) + its encode (encode_ms), from a prepared
// RaycastAccel (one per volume version: a camera orbit reuses it); accel_ms is the build that an
// edit adds once, and frame_with_accel_ms the whole of a frame right after an edit. still_ms is a
// still frame (smooth normals, five-sample occlusion, anti-aliased edges) with its JPEG
// (quality 90, as the server pushes it), still_encode_ms that encode alone. cpu_ms is the CPU
// time of render + encode (all threads of the process): on a loaded machine wall time includes
// waiting for a core and CPU time does not, so it is the figure to compare there.
// interactive_ms is the full-rate Interactive frame (every pixel traced), streamed until previews
// replaced it on 2026-11-25, render alone, with interactive_cpu_ms its CPU time. Each thread
// count gets its own line: opt.threads, then 1 thread.
#include <chrono>
#include <ctime>
#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "bench.hpp"
#include "engine/image_io.hpp"
#include "engine/raycast.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double processCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) * 1e3 + double(t.tv_nsec) / 1e6;
}

}  // namespace

MARZIPAN_BENCH("raycast_512") {
  using namespace marzipan;
  using Clock = std::chrono::steady_clock;
  const int side = opt.quick ? 128 : 512;
  const int n = opt.quick ? 96 : 256;
  const double radius = opt.quick ? 30 : 100;
  const int reps = opt.quick ? 1 : 21;
  const Vec3 c{n / 2.0, n / 2.0, n / 2.0};
  const Volume sphere = makeSphere({n, n, n}, c, radius);
  const Camera camera{c + normalized(Vec3{1, 0.75, 1.25}) * (4.2 * radius), c, {0, 1, 0}, 40, side, side};

  std::vector<int> counts{opt.threads};
  if (opt.threads != 1) counts.push_back(1);
  for (int threads : counts) {
    ThreadPool pool(threads);
    std::vector<double> renderMs, encodeMs, cpuMs, accelMs, withAccelMs, stillMs, stillEncodeMs, fullMs, fullCpuMs;
    std::size_t bytes = 0;
    std::unique_ptr<RaycastAccel> accel;
    Frame last;
    const auto t = bench::measure(
        reps,
        [&] {
          const auto t0 = Clock::now();
          accel = std::make_unique<RaycastAccel>(sphere, pool);
          accelMs.push_back(msSince(t0));
        },
        [&] {
          const double cpu0 = processCpuMs();
          auto t0 = Clock::now();
          Frame frame = render(*accel, camera, Shading::Lit, pool, FrameQuality::Preview);
          renderMs.push_back(msSince(t0));
          t0 = Clock::now();
          bytes = encodeJpeg(frame.rgb, frame.width, frame.height, 75).size();
          encodeMs.push_back(msSince(t0));
          cpuMs.push_back(processCpuMs() - cpu0);
          withAccelMs.push_back(accelMs.back() + renderMs.back() + encodeMs.back());
          last = std::move(frame);
        });
    for (int i = 0; i < reps; ++i) {
      const double cpu0 = processCpuMs();
      const auto t0 = Clock::now();
      const Frame full = render(*accel, camera, Shading::Lit, pool, FrameQuality::Interactive);
      fullMs.push_back(msSince(t0));
      fullCpuMs.push_back(processCpuMs() - cpu0);
    }
    for (int i = 0; i < reps; ++i) {
      const auto t0 = Clock::now();
      const Frame still = render(*accel, camera, Shading::Lit, pool, FrameQuality::Still);
      const auto t1 = Clock::now();
      encodeJpeg(still.rgb, still.width, still.height, 90);
      stillMs.push_back(msSince(t0));
      stillEncodeMs.push_back(msSince(t1));
    }
    std::size_t hits = 0;
    for (float d : last.depth) hits += std::isfinite(d) ? 1 : 0;
    const double render = median(renderMs);
    bench::emit("raycast_512", threads, t,
                {{"width", side},
                 {"height", side},
                 {"volume", n},
                 {"radius", radius},
                 {"render_ms", render},
                 {"encode_ms", median(encodeMs)},
                 {"cpu_ms", median(cpuMs)},
                 {"accel_ms", median(accelMs)},
                 {"frame_with_accel_ms", median(withAccelMs)},
                 {"interactive_ms", median(fullMs)},
                 {"interactive_cpu_ms", median(fullCpuMs)},
                 {"still_ms", median(stillMs)},
                 {"still_encode_ms", median(stillEncodeMs)},
                 {"pixels_per_s", double(side) * side / (render / 1000.0)},
                 {"hit_fraction", double(hits) / (double(side) * side)},
                 {"jpeg_bytes", bytes}});
  }
}
