// The sessions this server has loaded, and how a session comes and goes: created, found or
// loaded from its storage, clients admitted and leaving, unloaded when idle or left unchanged,
// closed when it is no longer safely served here. Also the bounds on creating sessions and the
// lobby deadline of connections in no session.
//
// Conventions:
// - Threads: the map, the loads in progress, the per-address create counts and each session's
//   clientCount/emptySince are guarded by the registry's lock; admit, leave, unload and
//   closeBroken run on the session's strand; find/create/findOrLoad on a connection's pump.
// - One loader per id: concurrent joins of a session at rest wait for the first one's load.
// - max_sessions counts sessions loaded and loading, and is checked before any work.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <deque>
#include <functional>
#include <future>
#include <optional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/rpc.hpp"
#include "service/hub/live_session.hpp"
#include "service/hub/request.hpp"

namespace marzipan::service {

struct HubCore;

// A grid size as the session's description gives it: [x, y, z] in voxels.
nlohmann::json sizeJson(Int3 dims);
// The session's base colour as the wire writes it: [r, g, b] (session.create/join/fork results).
nlohmann::json baseColorJson(const Volume& vol);

class SessionRegistry {
 public:
  explicit SessionRegistry(HubCore& hub) : hub_(hub) {}

  std::size_t count() const;
  std::vector<std::shared_ptr<LiveSession>> all() const;
  // The session registered under id (loaded, or being closed), or null.
  std::shared_ptr<LiveSession> find(const std::string& id) const;
  // s, while it is still the session registered under its id; else null.
  std::shared_ptr<LiveSession> current(const LiveSession& s) const;
  void clear();

  // A new session for c, registered at once; its volume (and, with a persistent storage, its
  // lease and first snapshot) is built on its strand before anything else runs there. Counts
  // the create against max_creates_per_minute (per connection and per address) first.
  std::shared_ptr<LiveSession> create(HubClient& c, const protocol::CreateParams& p);
  // The same with the volume build() makes on the new session's strand (session.fork: a copy
  // of another session's volume, sharing its bricks); proposed: the id, else a random one.
  // counted: the caller counted this create already (countCreate), before the work it needed.
  std::shared_ptr<LiveSession> create(HubClient& c, const std::optional<std::string>& proposed,
                                      std::function<Volume(HubCore&)> build, bool counted = false);
  // Counts a create of c against max_creates_per_minute (per connection and per address), or
  // refuses it (-32004). On c's pump, or on a strand while the pump waits for the request.
  void countCreate(HubClient& c);
  // The live session of this id, loading it from the storage when it sleeps there.
  std::shared_ptr<LiveSession> findOrLoad(const std::string& id, const std::string& token);

  // On the strand: c becomes a client of s; the response holds the session's description and
  // is followed by the full splat buffer (splats mode) and session.clients to the others.
  // `name`: its display name (default "Sculptor N", N its client id); it gets a colour.
  void admit(LiveSession& s, const std::shared_ptr<HubClient>& c, bool readOnly, protocol::ViewMode view, Reply& r,
             const std::optional<std::string>& name = std::nullopt);
  // On the strand: c leaves s (ending its stroke); the others hear of it. A session nobody
  // changed is unloaded when its last client leaves.
  void leave(LiveSession& s, HubClient& c);
  // On the strand: saves (with a persistent storage) and forgets a session without clients.
  void unload(LiveSession& s, const char* why);
  // On the strand: forgets a session whose in-memory state may be ahead of its journal, closing
  // its clients' connections (1011).
  void closeBroken(LiveSession& s);

  // Closes c once it has been in no session for the lobby time.
  void scheduleLobbyCheck(const std::weak_ptr<HubClient>& weak, std::chrono::milliseconds delay);

 private:
  std::shared_ptr<LiveSession> load(const std::string& id, const std::string& token);
  protocol::RpcException sessionsFull() const;
  void scheduleIdleCheck();
  void unloadIdle();

  HubCore& hub_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<LiveSession>> sessions_;
  std::map<std::string, std::shared_future<std::shared_ptr<LiveSession>>> loading_;
  std::map<std::string, std::deque<Clock::time_point>> createsByAddress_;  // in the last minute
  std::atomic<bool> idleCheckScheduled_{false};
};

}  // namespace marzipan::service
