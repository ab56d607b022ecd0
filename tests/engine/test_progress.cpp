// Progress and cancellation of the local tools (engine/progress.hpp): a brush, a stroke of
// separate groups and a CSG tool stop part way when cancelled, throw Cancelled and leave the
// volume exactly as it was (same digest); uncancelled, they count their unit of work.
#include <catch2/catch.hpp>

#include <future>
#include <thread>
#include <utility>

#include "engine/csg.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/progress.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

namespace {

// Runs op on a thread of its own under a Progress that reports at every advance. At its first
// report the op's thread waits until this thread has cancelled it, so that the cancel comes
// from another thread and always part way through. Returns the fraction done when the op
// threw Cancelled (and fails when it did not throw it).
template <class Op>
double cancelPartWay(Op op) {
  std::promise<void> reported, cancelled;
  std::shared_future<void> cancelledFuture = cancelled.get_future().share();
  bool first = true;
  Progress progress(
      [&](double) {
        if (!std::exchange(first, false)) return;
        reported.set_value();
        cancelledFuture.wait();
      },
      std::chrono::milliseconds(0));
  auto running = std::async(std::launch::async, [&] {
    const Progress::Scope scope(progress);
    op();
  });
  reported.get_future().wait();
  progress.cancel();
  cancelled.set_value();
  REQUIRE_THROWS_AS(running.get(), Cancelled);
  return progress.fraction();
}

}  // namespace

TEST_CASE("a brush over most of a 192^3 volume, cancelled from another thread, stops part way and changes nothing",
          "[progress]") {
  Volume v = makeSphere({192, 192, 192}, {96, 96, 96}, 70);
  const std::uint64_t before = digest(v);
  const double fraction = cancelPartWay([&] { addBlob(v, {{96, 96, 166}, 100, 1}); });
  INFO("fraction done when cancelled: " << fraction);
  CHECK(fraction > 0);
  CHECK(fraction < 0.5);  // the first report comes after the gather; the march is far off
  CHECK(digest(v) == before);
}

TEST_CASE("smoothing on two threads, cancelled in its sub-steps, stops and changes nothing", "[progress]") {
  // The 32 sub-steps run as pieces that two threads take in turn; one thread's Cancelled must
  // stop the other too (it would otherwise wait for the piece next to it for ever).
  Volume v = makeSphere({128, 128, 128}, {64, 64, 64}, 45);
  const std::uint64_t before = digest(v);
  ThreadPool pool(2);
  // The sub-steps are the share from 0.15 to 0.3 of the call (level_set/stroke.cpp). The thread that
  // crosses `at` cancels from its report; while it reports, the other thread's advances skip
  // theirs (progress.hpp), so a reporter descheduled before its cancel (a loaded machine) lets
  // the other run the remaining sub-steps: the cancel then lands in the march, which must
  // change nothing either. Such a run is tried again; one of a few must stop in the sub-steps.
  for (const double at : {0.16, 0.22, 0.28}) {
    double stoppedAt = 1;
    for (int attempt = 0; attempt < 8 && !(stoppedAt < 0.3); ++attempt) {
      Progress progress(
          [&](double fraction) {
            if (fraction > at) progress.cancel();
          },
          std::chrono::milliseconds(0));
      {
        const Progress::Scope scope(progress);
        REQUIRE_THROWS_AS(smooth(v, {{64, 64, 109}, 40, 1}, pool), Cancelled);
      }
      stoppedAt = progress.fraction();
      INFO("cancelled past " << at << ", stopped at " << stoppedAt << " (attempt " << attempt << ")");
      CHECK(stoppedAt > at);
      CHECK(digest(v) == before);
    }
    INFO("cancelled past " << at << ", last stopped at " << stoppedAt);
    CHECK(stoppedAt < 0.3);
  }
  // A report that throws once (progress.hpp: it propagates out of the call) does the same,
  // from whichever thread counted the step; the other thread must not wait for that piece.
  bool thrown = false;
  Progress failing(
      [&](double fraction) {
        if (fraction > 0.2 && !std::exchange(thrown, true)) throw std::runtime_error("report failed");
      },
      std::chrono::milliseconds(0));
  {
    const Progress::Scope scope(failing);
    REQUIRE_THROWS_AS(smooth(v, {{64, 64, 109}, 40, 1}, pool), std::runtime_error);
  }
  CHECK(digest(v) == before);
}

TEST_CASE("a CSG tool cancelled from another thread stops part way and changes nothing, also an intersect",
          "[progress]") {
  Volume v = makeSphere({160, 160, 160}, {80, 80, 80}, 60);
  const std::uint64_t before = digest(v);
  for (const CsgOp op : {CsgOp::Add, CsgOp::Intersect}) {
    CsgParams p;
    p.op = op;
    p.shape = ToolShape::Sphere;
    p.center = {80, 80, 120};
    p.radius = 70;
    const double fraction = cancelPartWay([&] { applyCsg(v, p); });
    INFO("fraction done when cancelled: " << fraction);
    CHECK(fraction > 0);
    CHECK(fraction < 1);
    CHECK(digest(v) == before);
  }
}

TEST_CASE("a stroke cancelled in its second group puts back the first group it already wrote", "[progress]") {
  Volume v = makeSphere({128, 128, 128}, {64, 64, 64}, 50);
  const std::uint64_t before = digest(v);
  // Two dabs on opposite sides of the sphere: two groups, each half of the call's unit.
  const StrokeDab dabs[] = {{{64, 64, 14}, 1.0}, {{64, 64, 114}, 1.0}};
  // Cancelled in the second group's evolution (0.6), in its march (0.8).
  for (const double at : {0.6, 0.8}) {
    Progress progress(
        [&](double fraction) {
          if (fraction > at) progress.cancel();
        },
        std::chrono::milliseconds(0));
    {
      const Progress::Scope scope(progress);
      REQUIRE_THROWS_AS(applyStroke(v, {Brush::AddBlob, 12, 1}, dabs, {}), Cancelled);
    }
    INFO("cancelled past " << at << ", stopped at " << progress.fraction());
    CHECK(progress.fraction() > at);
    CHECK(progress.fraction() < at + 0.1);
    CHECK(digest(v) == before);
  }

  // Not cancelled, the same stroke counts exactly its one unit and changes the volume.
  Progress counted;
  {
    const Progress::Scope scope(counted);
    applyStroke(v, {Brush::AddBlob, 12, 1}, dabs, {});
  }
  CHECK(counted.fraction() == Approx(1.0).epsilon(1e-9));
  CHECK(digest(v) != before);

  // The same dabs again with themselves as the stroke's memory add nothing: no redistance, and
  // still exactly the call's one unit.
  const std::uint64_t applied = digest(v);
  Progress again;
  {
    const Progress::Scope scope(again);
    applyStroke(v, {Brush::AddBlob, 12, 1}, dabs, dabs);
  }
  CHECK(again.fraction() == Approx(1.0).epsilon(1e-9));
  CHECK(digest(v) == applied);
}

TEST_CASE("a progress reports nothing before its first interval has passed", "[progress]") {
  int reports = 0;
  Progress progress([&](double) { ++reports; }, std::chrono::hours(1));
  progress.setTotal(4);
  for (int i = 0; i < 4; ++i) progress.advance(1);
  CHECK(reports == 0);
  CHECK(progress.fraction() == 1.0);
}
