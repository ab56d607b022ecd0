// Handlers of session.create, session.fork, session.join, session.leave, session.stats and op.cancel
// (service/hub/methods.hpp).
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"
#include "service/hub/secrets.hpp"
#include "service/measures_json.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;
using protocol::ViewMode;

namespace {

void checkProtocol(const std::optional<int>& major) {
  if (major && *major != protocol::kProtocolMajor)
    throw RpcException(RpcCode::UnsupportedProtocol,
                       "protocol major version " + std::to_string(*major) + " is not supported; this server speaks " +
                           std::to_string(protocol::kProtocolMajor) + "." + std::to_string(protocol::kProtocolMinor),
                       {{"field", "protocol"},
                        {"supported", {{"major", protocol::kProtocolMajor}, {"minor", protocol::kProtocolMinor}}}});
}

void refuseSecondSession(const HubClient& c) {
  if (c.session) throw RpcException(RpcCode::AlreadyInSession, "already in a session: session.leave first");
}

}  // namespace

void sessionCreate(HubCore& hub, const Call& call) {
  const std::shared_ptr<HubClient>& c = call.client;
  const protocol::CreateParams p = protocol::parseCreateParams(call.req.params);
  checkProtocol(p.protocol);
  refuseSecondSession(*c);
  const int maxSide = hub.limits().maxGridSide;
  for (int a = 0; a < 3; ++a)
    if (p.size[a] > maxSide)
      throw RpcException(RpcCode::LimitExceeded,
                         "\"size\"[" + std::to_string(a) + "] " + std::to_string(p.size[a]) +
                             " is over the server's max_grid_side " + std::to_string(maxSide),
                         {{"limit", "max_grid_side"}, {"value", p.size[a]}, {"max", maxSide}, {"field", "size"}});
  std::shared_ptr<LiveSession> s = hub.registry.create(*c, p);
  // c->session is set only once admitted: a refused create leaves the connection as it was.
  hub.onStrand(c, s, call.req.id, call.arrived, false, call.access,
               [self = hub.shared_from_this(), c, s, view = p.view, dims = p.size, solid = p.solid,
                name = p.name, splats = p.splats](LiveSession& ls, Reply& r) {
                 self->registry.admit(ls, c, false, view, r, name);
                 c->splats = splats;
                 c->session = s;
                 r.result["token"] = ls.secrets.token;
                 r.result["view_token"] = ls.secrets.viewToken;
                 self->log("session " + ls.id + ": created (" + solidKindName(solid) + " " + std::to_string(dims.x) +
                           "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z) + ") by " + c->peer);
               });
}

namespace {

// The second half of a fork, on the old session's strand: the new session from `volume`, the
// caller moved into it.
void forkFrom(const std::shared_ptr<HubCore>& self, const std::shared_ptr<HubClient>& c,
              const std::shared_ptr<LiveSession>& old, const std::optional<json>& id, Clock::time_point arrived,
              const Volume& volume) {
  std::shared_ptr<LiveSession> fresh;
  ViewMode view = ViewMode::None;
  const std::uint64_t from = volume.revision();
  try {
    if (old->unloaded || !old->session || c->session != old)
      throw RpcException(RpcCode::NotInSession, "the session was closed; join it again");
    fresh = self->registry.create(*c, std::nullopt, [volume](HubCore&) { return volume; }, true);
    // Frames need a camera sent again (view.set); splats follow as after session.create.
    view = c->mode == ViewMode::Splats ? ViewMode::Splats : ViewMode::None;
    self->registry.leave(*old, *c);
    c->session.reset();
  } catch (...) {
    self->sendError(*c, id, failureOf(std::current_exception(), self->options.events.log));
    return self->finish(c);
  }
  self->onStrand(c, fresh, id, arrived, false, Access::Anyone,
                 [self, c, fresh, view, from, oldId = old->id, name = c->name](LiveSession& ls, Reply& r) {
                   self->registry.admit(ls, c, false, view, r, name);  // the fork keeps the caller's name
                   c->session = fresh;
                   r.result["token"] = ls.secrets.token;
                   r.result["view_token"] = ls.secrets.viewToken;
                   r.result["forked_from"] = {{"session", oldId}, {"revision", from}};
                   self->log("session " + ls.id + ": forked from " + oldId + " at revision " + std::to_string(from) +
                             " by " + c->peer);
                 });
}

}  // namespace

void sessionFork(HubCore& hub, const Call& call) {
  const std::optional<std::uint64_t> revision = protocol::parseForkParams(call.req.params);
  const std::shared_ptr<HubClient>& c = call.client;
  std::shared_ptr<LiveSession> old = c->session;
  auto running = hub.track(c, call.req.id);
  // Not through onStrand: the old session's strand takes the volume and lets the caller go, then
  // the new one's admits it and answers. The connection's pump waits for this request, so the
  // pump-only fields (creates, session) are touched by no one else meanwhile. An earlier
  // revision is rebuilt on the workers, the strand free meanwhile, and the create is counted
  // before that work: a refused fork costs what a create does.
  old->strand->post([self = hub.shared_from_this(), c, old, id = call.req.id, arrived = call.arrived, revision,
                     running] {
    try {
      if (old->unloaded || !old->session || c->session != old)
        throw RpcException(RpcCode::NotInSession, "the session was closed; join it again");
      self->registry.countCreate(*c);
    } catch (...) {
      self->sendError(*c, id, failureOf(std::current_exception(), self->options.events.log));
      return self->finish(c);
    }
    if (!revision) {
      running->done();
      return forkFrom(self, c, old, id, arrived, old->session->snapshot());
    }
    // -32602 "revision" before anything changes.
    self->withVersion(
        old, *revision, running,
        [self, c, old, id, arrived](std::shared_ptr<const Volume> v) { forkFrom(self, c, old, id, arrived, *v); },
        [self, c, id](std::exception_ptr e) {
          self->sendError(*c, id, failureOf(e, self->options.events.log));
          self->finish(c);
        });
  });
}

void sessionJoin(HubCore& hub, const Call& call) {
  const std::shared_ptr<HubClient>& c = call.client;
  const protocol::JoinParams p = protocol::parseJoinParams(call.req.params);
  checkProtocol(p.protocol);
  refuseSecondSession(*c);
  std::shared_ptr<LiveSession> s = hub.registry.findOrLoad(p.session, p.token);
  bool readOnly = false;
  if (sameSecret(s->secrets.token, p.token)) readOnly = false;
  else if (sameSecret(s->secrets.viewToken, p.token)) readOnly = true;
  else throw RpcException(RpcCode::BadToken, "the token opens neither edit nor view rights of this session", {{"field", "token"}});
  // c->session is set only once admitted: a refused join (a full session) grants nothing.
  hub.onStrand(c, s, call.req.id, call.arrived, false, call.access,
               [self = hub.shared_from_this(), c, s, view = p.view, readOnly, name = p.name,
                splats = p.splats](LiveSession& ls, Reply& r) {
                 self->registry.admit(ls, c, readOnly, view, r, name);
                 c->splats = splats;
                 // An editor may share a view link; a view client learns nothing more than it had.
                 if (!readOnly) r.result["view_token"] = ls.secrets.viewToken;
                 c->session = s;
                 self->log("session " + ls.id + ": client " + std::to_string(c->clientId) + " (" + c->peer + ") joined" +
                           (readOnly ? " read-only" : "") + ", " + std::to_string(ls.clients.size()) + " in all");
               });
}

void sessionLeave(HubCore& hub, const Call& call) {
  protocol::parseNoParams(call.req.params, call.req.method);
  hub.onStrand(call, false, [self = hub.shared_from_this(), c = call.client](LiveSession& s, Reply& r) {
    self->registry.leave(s, *c);
    r.result = {{"session", s.id}};
    c->session.reset();
  });
}

void sessionStats(HubCore& hub, const Call& call) {
  protocol::parseNoParams(call.req.params, call.req.method);
  // The measures read every brick: off the strand, on the snapshot, so edits go on meanwhile.
  hub.offStrand(
      call, [](const Volume& vol, std::uint64_t, Reply& r) { putMeasures(r.result, measure(vol)); },
      [](LiveSession& s, Reply& r) {
        const SessionStats st = s.session->counters();
        r.result = {{"session", s.id},
                    {"size", sizeJson(s.session->volume().dims())},
                    {"revision", st.revision},
                    {"clients", Broadcaster::clientList(s)},
                    {"memory_bytes", st.memoryBytes},
                    {"history_bytes", st.historyBytes},
                    {"can_undo", st.canUndo},
                    {"can_redo", st.canRedo}};
      });
}

// An op.cancel normally overtakes the queue (Hub::text); one that reaches the pump was spelled
// so that Hub::text did not see it (escapes): nothing of this connection runs while the pump
// handles a message, so there is nothing to cancel.
void opCancel(HubCore& hub, const Call& call) {
  protocol::parseNoParams(call.req.params, call.req.method);
  hub.sendResult(*call.client, call.req.id, {{"cancelled", false}});
  hub.finish(call.client);
}

}  // namespace marzipan::service
