// How a request's work runs (service/hub/core.hpp): on its session's strand or off it on a
// snapshot, long operations with progress, cancel and a budget, and the answers.
#include <cstdio>

#include "service/hub/core.hpp"
#include "service/hub/outbox.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;

// --- answering -------------------------------------------------------------------------------------

void HubCore::sendResult(HubClient& c, const std::optional<json>& id, const json& result) {
  if (id) c.link->sendText(protocol::resultText(*id, result));
}

void HubCore::sendResult(HubClient& c, const std::optional<json>& id, const json& result, const std::string& resultJson) {
  if (resultJson.empty()) return sendResult(c, id, result);
  sendResultText(c, id, resultJson);
}

void HubCore::sendResultText(HubClient& c, const std::optional<json>& id, std::string_view resultJson) {
  if (id) c.link->sendText(protocol::resultTextOfJson(*id, resultJson));
}

void HubCore::sendError(HubClient& c, const json& id, bool notification, const Failure& f) {
  if (options.events.error) options.events.error(int(f.code));
  if (!notification) c.link->sendText(protocol::errorText(id, f.code, f.message, f.data));
}

void HubCore::sendError(HubClient& c, const std::optional<json>& id, const Failure& f) {
  sendError(c, id ? *id : json(nullptr), !id.has_value(), f);
}

// --- running work ----------------------------------------------------------------------------------

void HubCore::checkAccess(const HubClient& c, Access access) {
  if (access == Access::Editor && c.readOnly)
    throw RpcException(RpcCode::ReadOnly, "this client joined with the view token: edits are refused");
}

void HubCore::onStrand(const Call& call, bool edit, std::function<void(LiveSession&, Reply&)> fn) {
  onStrand(call.client, call.client->session, call.req.id, call.arrived, edit, call.access, std::move(fn));
}

void HubCore::onStrand(const std::shared_ptr<HubClient>& c, std::shared_ptr<LiveSession> s, const std::optional<json>& id,
                       Clock::time_point arrived, bool edit, Access access,
                       std::function<void(LiveSession&, Reply&)> fn) {
  s->strand->post([self = shared_from_this(), c, s, id, arrived, edit, access, fn = std::move(fn)] {
    // The response, the change's notification and its delta leave as one hand-over per client.
    const Outbox::Scope held;
    Reply r;
    try {
      if (s->unloaded || !s->session) {
        if (c->session == s) c->session.reset();
        if (s->failure) std::rethrow_exception(s->failure);
        throw RpcException(RpcCode::NotInSession, "the session was closed; join it again");
      }
      checkAccess(*c, access);
      fn(*s, r);
      if (edit) self->endStaleStrokes(*s, r);
      if (r.record) {
        self->durability.persist(*s, r.record);
      } else if (edit) {
        self->durability.confirmHeld(*s);
      }
      if (r.frame) c->link->sendBinary(r.frame, false);
      self->sendResult(*c, id, r.result, r.resultJson);
      for (const Reply::Merged& m : r.merged) self->sendResultText(*c, m.id, m.resultJson);
      if (edit && self->options.events.editLatency) {
        const Clock::time_point now = Clock::now();
        self->options.events.editLatency(std::chrono::duration<double>(now - arrived).count());
        for (const Reply::Merged& m : r.merged)
          self->options.events.editLatency(std::chrono::duration<double>(now - m.arrived).count());
      }
      if (r.after) r.after();
    } catch (...) {
      // A merged message shares the fate of the work that carried it (a journal that failed
      // rolled the one application back).
      const Failure f = failureOf(std::current_exception(), self->options.events.log);
      self->sendError(*c, id, f);
      for (const Reply::Merged& m : r.merged) self->sendError(*c, m.id, f);
    }
    self->finish(c);
  });
}

void HubCore::offStrand(const Call& call, std::function<void(const Volume&, std::uint64_t revision, Reply&)> fn,
                        std::function<void(LiveSession&, Reply&)> atStrand, std::optional<std::uint64_t> at) {
  const std::shared_ptr<HubClient>& c = call.client;
  std::shared_ptr<LiveSession> s = c->session;
  // An earlier revision may have to be rebuilt: a long operation, cancellable.
  std::shared_ptr<RunningOp> running = at ? track(c, call.req.id) : nullptr;
  // On the strand, with the volume to read: the reply started there, the work on the workers.
  auto answer = [self = shared_from_this(), c, s, id = call.req.id, fn = std::move(fn),
                 atStrand = std::move(atStrand)](std::shared_ptr<const Volume> vol, std::uint64_t revision) {
    auto started = std::make_shared<Reply>();
    if (atStrand) atStrand(*s, *started);
    self->workers.post([self, c, id, vol, revision, fn, started] {
      Reply& r = *started;
      try {
        fn(*vol, revision, r);
        if (r.frame) c->link->sendBinary(r.frame, false);
        self->sendResult(*c, id, r.result);
      } catch (...) {
        self->sendError(*c, id, failureOf(std::current_exception(), self->options.events.log));
      }
      self->finish(c);
    });
  };
  s->strand->post([self = shared_from_this(), c, s, id = call.req.id, answer = std::move(answer), at, running] {
    if (s->unloaded || !s->session) {
      self->sendError(*c, id, {RpcCode::NotInSession, "the session was closed", nullptr});
      return self->finish(c);
    }
    if (!at) return answer(std::make_shared<const Volume>(s->session->snapshot()), s->session->revision());
    self->withVersion(
        s, *at, running, [answer, revision = *at](std::shared_ptr<const Volume> vol) { answer(std::move(vol), revision); },
        [self, c, id](std::exception_ptr e) {
          self->sendError(*c, id, failureOf(e, self->options.events.log));
          self->finish(c);
        });
  });
}

void HubCore::withVersion(const std::shared_ptr<LiveSession>& s, std::uint64_t revision,
                          const std::shared_ptr<RunningOp>& running,
                          std::function<void(std::shared_ptr<const Volume>)> then,
                          std::function<void(std::exception_ptr)> fail) {
  try {
    if (s->unloaded || !s->session) throw RpcException(RpcCode::NotInSession, "the session was closed; join it again");
    std::variant<Volume, Rebuild> version = s->session->versionAt(revision);
    if (Volume* ready = std::get_if<Volume>(&version)) {
      running->done();
      return then(std::make_shared<const Volume>(std::move(*ready)));
    }
    const Rebuild& rb = std::get<Rebuild>(version);
    checkBudget(rb.voxels(), "rebuilding this revision");
    if (s->rebuilding) {
      s->awaitingRebuild.push_back([self = shared_from_this(), s, revision, running, then, fail] {
        self->withVersion(s, revision, running, then, fail);
      });
      return;
    }
    s->rebuilding = true;
    // Off the strand: the session's edits go on while an old version is unpacked.
    workers.post([self = shared_from_this(), s, rb = std::get<Rebuild>(std::move(version)), running, then, fail] {
      std::shared_ptr<const Volume> built;
      std::exception_ptr error;
      try {
        built = std::make_shared<const Volume>(self->build(rb, *running));
      } catch (...) {
        error = std::current_exception();
      }
      s->strand->post([self, s, rb, built, error, then, fail] {
        if (built && s->session && !s->unloaded) s->session->keep(rb, *built);
        if (error) fail(error);
        else then(built);
        self->rebuildEnded(*s);
      });
    });
  } catch (...) {
    fail(std::current_exception());
  }
}

void HubCore::rebuildEnded(LiveSession& s) {
  s.rebuilding = false;
  while (!s.rebuilding && !s.awaitingRebuild.empty()) {
    std::function<void()> next = std::move(s.awaitingRebuild.front());
    s.awaitingRebuild.pop_front();
    next();
  }
}

void HubCore::endStaleStrokes(LiveSession& s, Reply& r) {
  const std::vector<StrokeId> ended = s.session->endStaleStrokes(
      limits().maxVolumeBytes, std::chrono::duration_cast<std::chrono::milliseconds>(limits().strokeIdle).count());
  if (ended.empty()) return;
  std::string ids;
  for (const StrokeId id : ended) ids += (ids.empty() ? "" : ", ") + std::to_string(id);
  log("session " + s.id + ": ended open stroke(s) " + ids + " (idle, or holding old bricks over max_volume_bytes)");
  r.record = [made = std::move(r.record), ended] {
    json records = made ? made() : json::array();
    if (!records.is_array()) records = json::array({std::move(records)});
    for (const StrokeId id : ended) records.push_back({{"stroke_end", id}});
    return records;
  };
}

Volume HubCore::build(const Rebuild& rb, RunningOp& running) {
  running.progress->setTotal(double(rb.steps()));
  std::optional<Workers::LongTask> longTask;
  if (rb.voxels() > kLongOpVoxels) longTask.emplace(workers);
  const Progress::Scope scope(*running.progress);
  Volume v = rb.run();
  running.done();
  return v;
}

// --- long operations -------------------------------------------------------------------------------

void HubCore::RunningOp::done() {
  if (!std::exchange(registered, false)) return;
  client->clearRunning(progress);
  const std::lock_guard lock(hub->mutex_);
  hub->runningOps_.erase(progress.get());
}

std::shared_ptr<HubCore::RunningOp> HubCore::track(const std::shared_ptr<HubClient>& c, const std::optional<json>& id) {
  auto progress = std::make_shared<Progress>(
      [link = c->link, request = id.value_or(json(nullptr))](double fraction) {
        link->sendText(protocol::notificationText("op.progress", {{"request", request}, {"fraction", fraction}}));
        Outbox::flush();  // now, not when the operation ends
      },
      kProgressInterval);
  auto op = std::make_shared<RunningOp>(RunningOp{shared_from_this(), c, progress});
  c->setRunning(progress);
  const std::lock_guard lock(mutex_);
  runningOps_.insert(progress.get());
  if (stopping_) progress->cancel();
  return op;
}

void HubCore::checkBudget(double voxels, const char* what) const {
  if (voxels <= limits().maxOpVoxels) return;
  char text[160];
  std::snprintf(text, sizeof text, "%s would process about %.3g voxels, over the server's max_op_voxels %.3g", what, voxels,
                limits().maxOpVoxels);
  throw RpcException(RpcCode::LimitExceeded, std::string(text) + "; use fewer iterations, a smaller radius or fewer dabs",
                     {{"limit", "max_op_voxels"}, {"value", voxels}, {"max", limits().maxOpVoxels}});
}

// --- shutting down ---------------------------------------------------------------------------------

bool HubCore::stopping() const {
  const std::lock_guard lock(mutex_);
  return stopping_;
}

bool HubCore::stop() {
  const std::lock_guard lock(mutex_);
  if (std::exchange(stopping_, true)) return false;
  // Long operations stop at their next chunk or dab and change nothing; the others finish.
  for (Progress* p : runningOps_) p->cancel();
  return true;
}

}  // namespace marzipan::service
