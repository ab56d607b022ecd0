#include "service/hub/registry.hpp"

#include <algorithm>

#include "engine/solids.hpp"
#include "service/client_address.hpp"
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"
#include "service/hub/secrets.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;
using protocol::ViewMode;

json sizeJson(Int3 d) { return json::array({d.x, d.y, d.z}); }

json baseColorJson(const Volume& v) {
  const Rgb8 c = v.baseColor();
  return protocol::colorJson(SrgbColor{c.r, c.g, c.b});
}

namespace {

json limitsJson(const HubLimits& l) {
  return {{"max_text_bytes", l.maxTextBytes},
          {"max_binary_bytes", l.maxBinaryBytes},
          {"max_grid_side", l.maxGridSide},
          {"max_sessions", l.maxSessions},
          {"max_clients_per_session", l.maxClientsPerSession},
          {"max_dabs", l.maxDabs},
          {"max_frame_side", l.maxFrameSide},
          {"history_bytes", l.historyBytes},
          {"idle_session_seconds", l.idleSession.count()},
          {"ping_seconds", l.ping.count()},
          {"max_queue_bytes", l.maxQueuedBytes},
          {"max_connections", l.maxConnections},
          {"max_connections_per_address", l.maxConnectionsPerAddress},
          {"lobby_seconds", l.lobby.count()},
          {"max_volume_bytes", l.maxVolumeBytes},
          {"max_output_bytes", l.maxOutputBytes},
          {"max_vdb_bytes", l.maxVdbBytes},
          {"max_creates_per_minute", l.maxCreatesPerMinute},
          {"max_creates_per_address_per_minute", l.maxCreatesPerAddressPerMinute},
          {"max_session_age_days", l.maxSessionAge.count() / 24},
          {"max_op_voxels", l.maxOpVoxels},
          {"volume_formats", volumeFormatsJson()}};
}

}  // namespace

std::size_t SessionRegistry::count() const {
  const std::lock_guard lock(mutex_);
  return sessions_.size();
}

std::vector<std::shared_ptr<LiveSession>> SessionRegistry::all() const {
  std::vector<std::shared_ptr<LiveSession>> out;
  const std::lock_guard lock(mutex_);
  for (const auto& [id, live] : sessions_) out.push_back(live);
  return out;
}

std::shared_ptr<LiveSession> SessionRegistry::find(const std::string& id) const {
  const std::lock_guard lock(mutex_);
  const auto it = sessions_.find(id);
  return it != sessions_.end() ? it->second : nullptr;
}

std::shared_ptr<LiveSession> SessionRegistry::current(const LiveSession& s) const {
  const std::lock_guard lock(mutex_);
  const auto it = sessions_.find(s.id);
  return it != sessions_.end() && it->second.get() == &s ? it->second : nullptr;
}

void SessionRegistry::clear() {
  const std::lock_guard lock(mutex_);
  sessions_.clear();
}

RpcException SessionRegistry::sessionsFull() const {
  const HubLimits& l = hub_.limits();
  return RpcException(RpcCode::LimitExceeded, "the server holds its " + std::to_string(l.maxSessions) + " sessions; try later",
                      {{"limit", "max_sessions"}, {"max", l.maxSessions}});
}

// --- creating ----------------------------------------------------------------------------------

void SessionRegistry::countCreate(HubClient& c) {
  const HubLimits& l = hub_.limits();
  const auto now = Clock::now();
  const auto minuteAgo = now - std::chrono::minutes(1);
  const auto refuse = [](const char* limit, std::size_t max, const std::string& who) {
    return RpcException(RpcCode::LimitExceeded,
                        std::to_string(max) + " sessions were created " + who + " in the last minute; try later",
                        {{"limit", limit}, {"max", max}, {"retry_after_ms", 60'000}});
  };
  while (!c.creates.empty() && c.creates.front() < minuteAgo) c.creates.pop_front();
  if (c.creates.size() >= l.maxCreatesPerMinute)
    throw refuse("max_creates_per_minute", l.maxCreatesPerMinute, "on this connection");
  {
    const std::lock_guard lock(mutex_);
    for (auto it = createsByAddress_.begin(); it != createsByAddress_.end();) {
      while (!it->second.empty() && it->second.front() < minuteAgo) it->second.pop_front();
      it = it->second.empty() ? createsByAddress_.erase(it) : std::next(it);
    }
    const std::string address = addressLimitKey(c.peer);
    auto& mine = createsByAddress_[address];
    if (mine.size() >= l.maxCreatesPerAddressPerMinute) {
      if (mine.empty()) createsByAddress_.erase(address);
      throw refuse("max_creates_per_address_per_minute", l.maxCreatesPerAddressPerMinute, "from this address");
    }
    mine.push_back(now);
  }
  c.creates.push_back(now);
}

std::shared_ptr<LiveSession> SessionRegistry::create(HubClient& c, const protocol::CreateParams& p) {
  const Int3 dims = p.size;
  const SolidKind solid = p.solid;
  const std::optional<SrgbColor> base = p.baseColor;
  return create(c, p.session, [dims, solid, base](HubCore& hub) {
    Volume v = makeSolid(solid, dims, Volume::kDefaultBand, hub.pool);
    if (base) v.setBaseColor(Rgb8{base->r, base->g, base->b});
    return v;
  });
}

std::shared_ptr<LiveSession> SessionRegistry::create(HubClient& c, const std::optional<std::string>& proposed,
                                                     std::function<Volume(HubCore&)> build, bool counted) {
  if (!counted) countCreate(c);
  const std::string id = proposed.value_or(randomText(kSessionIdChars));
  auto s = std::make_shared<LiveSession>(id, SessionSecrets{randomText(kTokenChars), randomText(kTokenChars)}, hub_.workers);
  const auto taken = [&] {
    return RpcException(RpcCode::SessionExists, "a session with id \"" + id + "\" exists already; propose another",
                        {{"field", "session"}});
  };
  // Asked before the lock: the storage may be remote (etcd). One at rest stays; a concurrent
  // create of the same id meets this one in the map.
  if (hub_.store->exists(id)) throw taken();
  {
    const std::lock_guard lock(mutex_);
    if (sessions_.count(id)) throw taken();
    if (sessions_.size() >= hub_.limits().maxSessions) throw sessionsFull();
    sessions_[id] = s;
  }
  HubCore::emit(hub_.options.events.sessions, 1);
  // The volume is built on the strand, before anything else can reach the new session.
  s->strand->post([self = hub_.shared_from_this(), s, build = std::move(build)] {
    try {
      s->session = std::make_unique<Session>(build(*self), self->limits().historyBytes);
      if (self->store->persistent()) {
        if (!self->store->acquire(s->id)) throw self->durability.heldElsewhere(s->id, "another server holds this session id");
        {
          const std::lock_guard lease(s->leaseMutex);
          s->leaseAcquired = true;
        }
        s->journal = self->store->create(s->id, s->secrets, s->session->volume());
        self->durability.scheduleLeaseRenewal();
      }
    } catch (const std::exception& e) {
      self->log("session " + s->id + ": creating it failed: " + e.what());
      s->failure = std::current_exception();
      s->session.reset();
      s->unloaded = true;
      {
        const std::lock_guard lock(self->registry.mutex_);
        self->registry.sessions_.erase(s->id);
      }
      HubCore::emit(self->options.events.sessions, -1);
    }
  });
  return s;
}

// --- finding and loading -------------------------------------------------------------------------

std::shared_ptr<LiveSession> SessionRegistry::findOrLoad(const std::string& id, const std::string& token) {
  std::shared_future<std::shared_ptr<LiveSession>> pending;
  std::promise<std::shared_ptr<LiveSession>> mine;
  {
    const std::lock_guard lock(mutex_);
    if (const auto it = sessions_.find(id); it != sessions_.end() && !it->second->unloaded) return it->second;
    if (const auto it = loading_.find(id); it != loading_.end()) pending = it->second;
    else if (sessions_.size() + loading_.size() >= hub_.limits().maxSessions) throw sessionsFull();
    else loading_.emplace(id, mine.get_future().share());
  }
  if (pending.valid()) {
    // The caller checks this client's token against the loaded session's secrets. A load that
    // failed (perhaps for the other joiner's token) is tried again with this one.
    try {
      return pending.get();
    } catch (...) {
      return findOrLoad(id, token);
    }
  }
  const auto settle = [&] {
    const std::lock_guard lock(mutex_);
    loading_.erase(id);
  };
  try {
    std::shared_ptr<LiveSession> s = load(id, token);
    settle();
    mine.set_value(s);
    return s;
  } catch (...) {
    settle();
    mine.set_exception(std::current_exception());
    throw;
  }
}

std::shared_ptr<LiveSession> SessionRegistry::load(const std::string& id, const std::string& token) {
  const auto& store = hub_.store;
  const std::optional<SessionSecrets> secrets = store->secrets(id);
  if (!secrets) throw RpcException(RpcCode::NoSuchSession, "no session with id \"" + id + "\"", {{"field", "session"}});
  if (!sameSecret(secrets->token, token) && !sameSecret(secrets->viewToken, token))
    throw RpcException(RpcCode::BadToken, "the token opens neither edit nor view rights of this session", {{"field", "token"}});
  if (!store->acquire(id))
    throw hub_.durability.heldElsewhere(id, "another server has session \"" + id + "\" loaded; connect with /ws?session=" +
                                                id + " through the load balancer, or to the server data.owner names");
  Recovered rec;
  try {
    rec = store->recover(id, hub_.limits().historyBytes, hub_.pool);
  } catch (...) {
    store->release(id);
    throw;
  }
  auto s = std::make_shared<LiveSession>(id, *secrets, hub_.workers);
  s->leaseAcquired = true;  // registered below, once loaded: nothing else sees it yet
  s->session = std::move(rec.session);
  // Client ids are the authors of the recovered steps: a newcomer must not be taken for one of
  // them by history.undo {scope: "mine"}.
  for (const StepInfo& step : s->session->steps()) {
    const std::string& a = step.author.id;
    if (!a.empty() && a.size() < 10 && std::all_of(a.begin(), a.end(), [](char ch) { return ch >= '0' && ch <= '9'; }))
      s->nextClient = std::max(s->nextClient, std::stoi(a) + 1);
  }
  s->journal = std::move(rec.journal);
  hub_.durability.scheduleLeaseRenewal();
  {
    const std::lock_guard lock(mutex_);
    // Its slot was counted in `loading_` when the load began.
    sessions_[id] = s;
  }
  HubCore::emit(hub_.options.events.sessions, 1);
  hub_.log("session " + id + ": loaded from " + store->where() + " at revision " + std::to_string(s->session->revision()) +
           " (" + std::to_string(rec.replayed) + " journal records replayed)");
  return s;
}

// --- clients -------------------------------------------------------------------------------------

void SessionRegistry::admit(LiveSession& s, const std::shared_ptr<HubClient>& c, bool readOnly, ViewMode view, Reply& r,
                            const std::optional<std::string>& name) {
  const HubLimits& l = hub_.limits();
  if (s.clients.size() >= l.maxClientsPerSession)
    throw RpcException(RpcCode::SessionFull, "the session has its " + std::to_string(l.maxClientsPerSession) + " clients",
                       {{"limit", "max_clients_per_session"}, {"max", l.maxClientsPerSession}});
  c->clientId = s.nextClient++;
  c->readOnly = readOnly;
  c->mode = view;
  c->stroke = 0;
  c->member = true;
  c->editor = !readOnly;
  c->rendering = c->renderAgain = false;  // a render of an earlier membership no longer counts
  c->name = name ? *name : "Sculptor " + std::to_string(c->clientId);
  c->color = PresenceRelay::colorFor(s);
  s.clients.push_back(c);
  hub_.presence.join(s, *c);
  {
    const std::lock_guard lock(mutex_);
    ++s.clientCount;
  }
  HubCore::emit(hub_.options.events.clients, 1);
  const Session& ss = *s.session;
  json clients = Broadcaster::clientList(s);
  r.result = {{"session", s.id},
              {"client", c->clientId},
              {"size", sizeJson(ss.volume().dims())},
              {"revision", ss.revision()},
              {"digest", digestText(ss.digest())},
              {"base_color", baseColorJson(ss.volume())},
              {"protocol", {{"major", protocol::kProtocolMajor}, {"minor", protocol::kProtocolMinor}}},
              {"limits", limitsJson(l)},
              {"can_undo", ss.canUndo()},
              {"can_redo", ss.canRedo()},
              {"read_only", c->readOnly},
              {"clients", clients}};
  r.after = [self = hub_.shared_from_this(), &s, c, clients = std::move(clients)] {
    if (c->mode == ViewMode::Splats) self->broadcast.sendFullSplats(s, *c, 0);
    self->broadcast.clients(s, c.get(), clients);
  };
}

void SessionRegistry::leave(LiveSession& s, HubClient& c) {
  const auto it = std::find_if(s.clients.begin(), s.clients.end(), [&](const auto& p) { return p.lock().get() == &c; });
  if (it == s.clients.end()) return;
  if (c.stroke) {
    try {
      s.session->endStroke(c.stroke);
      if (s.journal) s.journal->append({{"stroke_end", c.stroke}});
    } catch (const std::exception& e) {
      // Already closed by the session (a reload), or not journaled: replay then ends the stroke
      // at the end of the journal, which folds the same dabs into the same step.
      hub_.log("session " + s.id + ": ending client " + std::to_string(c.clientId) + "'s stroke: " + e.what());
    }
    c.stroke = 0;
  }
  s.clients.erase(it);
  hub_.presence.leave(s, c);
  c.mode = ViewMode::None;
  c.editor = false;
  c.member = false;
  c.outsideSince = Clock::now().time_since_epoch().count();
  {
    const std::lock_guard lock(mutex_);
    --s.clientCount;
    if (s.clientCount == 0) s.emptySince = Clock::now();
  }
  HubCore::emit(hub_.options.events.clients, -1);
  hub_.log("session " + s.id + ": client " + std::to_string(c.clientId) + " (" + c.peer + ") left, " +
           std::to_string(s.clients.size()) + " remain");
  hub_.broadcast.clients(s, nullptr, Broadcaster::clientList(s));
  // A session nobody changed holds nothing worth keeping in memory: its slot goes at once.
  if (s.clients.empty() && s.session->revision() == 0) return unload(s, "left unchanged");
  scheduleIdleCheck();
}

// --- going -----------------------------------------------------------------------------------------

void SessionRegistry::unload(LiveSession& s, const char* why) {
  if (s.unloaded || !s.clients.empty() || !s.session) return;
  const bool persistent = hub_.store->persistent();
  if (persistent && s.journal) hub_.durability.saveAndRelease(s, "unload");
  s.journal.reset();
  s.unloaded = true;
  {
    const std::lock_guard lock(mutex_);
    if (const auto it = sessions_.find(s.id); it != sessions_.end() && it->second.get() == &s) sessions_.erase(it);
  }
  HubCore::emit(hub_.options.events.sessions, -1);
  hub_.log("session " + s.id + ": " + why + ", " + (persistent ? "saved and unloaded" : "discarded (no --data-dir)"));
  s.session.reset();
}

void SessionRegistry::closeBroken(LiveSession& s) {
  s.unloaded = true;
  {
    const std::lock_guard lock(mutex_);
    if (const auto it = sessions_.find(s.id); it != sessions_.end() && it->second.get() == &s) sessions_.erase(it);
  }
  HubCore::emit(hub_.options.events.sessions, -1);
  HubCore::emit(hub_.options.events.clients, -std::int64_t(s.clients.size()));
  for (const auto& c : s.members()) c->link->close(1011, "the session is no longer served here; join it again");
  s.clients.clear();
}

void SessionRegistry::scheduleIdleCheck() {
  if (idleCheckScheduled_.exchange(true)) return;
  const auto delay = std::max<std::chrono::milliseconds>(
      std::chrono::milliseconds(100), std::chrono::duration_cast<std::chrono::milliseconds>(hub_.limits().idleSession) / 4);
  hub_.workers.postAfter(delay, [self = hub_.shared_from_this()] {
    self->registry.idleCheckScheduled_ = false;
    self->registry.unloadIdle();
  });
}

void SessionRegistry::unloadIdle() {
  std::vector<std::shared_ptr<LiveSession>> idle;
  bool more = false;
  {
    const std::lock_guard lock(mutex_);
    for (const auto& [id, s] : sessions_) {
      if (s->clientCount != 0) continue;
      if (Clock::now() - s->emptySince >= hub_.limits().idleSession) idle.push_back(s);
      else more = true;
    }
  }
  for (const auto& s : idle) s->strand->post([self = hub_.shared_from_this(), s] { self->registry.unload(*s, "idle"); });
  if (more) scheduleIdleCheck();
}

// --- connections outside a session ------------------------------------------------------------------

void SessionRegistry::scheduleLobbyCheck(const std::weak_ptr<HubClient>& weak, std::chrono::milliseconds delay) {
  hub_.workers.postAfter(delay, [self = hub_.shared_from_this(), weak] {
    const auto c = weak.lock();
    if (!c || c->queue.closed()) return;
    const auto lobby = std::chrono::duration_cast<std::chrono::milliseconds>(self->limits().lobby);
    const auto out = Clock::now() - Clock::time_point(Clock::duration(c->outsideSince.load()));
    if (c->member || out < lobby) {
      const auto left = c->member ? lobby : lobby - std::chrono::duration_cast<std::chrono::milliseconds>(out);
      return self->registry.scheduleLobbyCheck(weak, std::max(left, std::chrono::milliseconds(10)));
    }
    c->link->close(1008, "no session joined within " + std::to_string(self->limits().lobby.count()) + " s");
  });
}

}  // namespace marzipan::service
