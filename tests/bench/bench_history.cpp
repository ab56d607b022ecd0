// Two people sculpting one session (service/session.cpp, history.cpp): two strokes of
// interleaved one-dab messages on the 128^3 pig (64^3 with --quick), at either end of its back
// (no brick in common). With authors each stroke folds into its own step across the other's
// messages (History::fold repacks the step each time); without, every message is a step of its
// own. The whole run is timed, 2 x 30 messages (2 x 8 with --quick), and per message.
#include <cstddef>
#include <memory>
#include <string>

#include "bench.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "service/session.hpp"

namespace {

using namespace marzipan;
using namespace marzipan::bench;

MARZIPAN_BENCH("history_two_sculptors") {
  const int side = opt.quick ? 64 : 128;
  const int messages = opt.quick ? 8 : 30;
  const int reps = opt.quick ? 1 : 7;
  const Volume pig = makeSolid(SolidKind::Pig, {side, side, side});
  ThreadPool pool(opt.threads > 0 ? opt.threads : 1);
  for (const bool authored : {false, true}) {
    std::size_t steps = 0, bytes = 0;
    std::unique_ptr<service::Session> s;
    const Timing t = measure(
        reps, [&] { s = std::make_unique<service::Session>(pig); },
        [&] {
          const service::StepAuthor a{authored ? "a" : "", "A"}, b{authored ? "b" : "", "B"};
          const auto sa = s->beginStroke(protocol::BrushTool::AddBlob, side / 16.0, 1, {}, false, a);
          const auto sb = s->beginStroke(protocol::BrushTool::AddBlob, side / 16.0, 1, {}, false, b);
          for (int i = 0; i < messages; ++i) {
            // Rays straight down onto the back, one near each end of the pig, moving along it.
            const double u = double(i) / messages;
            const service::Ray ra{{side * (0.22 + 0.12 * u), side * 0.5, side * 2.0}, {0, 0, -1}};
            const service::Ray rb{{side * (0.66 + 0.12 * u), side * 0.5, side * 2.0}, {0, 0, -1}};
            s->strokeDabs(sa, {service::Dab{ra, std::nullopt}}, pool);
            s->strokeDabs(sb, {service::Dab{rb, std::nullopt}}, pool);
          }
          s->endStroke(sa);
          s->endStroke(sb);
          steps = s->history().undoSteps();
          bytes = s->history().bytes();
        });
    emit("history_two_sculptors", pool.threads(), t,
         {{"side", side},
          {"authored", authored},
          {"messages", 2 * messages},
          {"ms_per_message", t.median_ms / (2 * messages)},
          {"undo_steps", steps},
          {"history_bytes", bytes}});
  }
}

}  // namespace
