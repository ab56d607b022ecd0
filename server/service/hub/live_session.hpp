// A session as the hub holds it while it is loaded: the engine's Session, its journal, its
// strand and its clients.
//
// Conventions:
// - Threads: fields are grouped by the one context that may touch them (the session's strand,
//   the registry's lock, the lease's own lock); the atomics are read anywhere.
// - Ownership runs one way: connection -> HubClient -> LiveSession. A session knows its clients
//   by weak reference, so nothing needs breaking at shutdown.
#pragma once

#include <algorithm>
#include <atomic>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "service/hub/broadcast.hpp"
#include "service/hub/connection.hpp"
#include "service/hub/presence_relay.hpp"
#include "service/session.hpp"
#include "service/session_storage.hpp"
#include "service/workers.hpp"

namespace marzipan::service {

struct LiveSession : std::enable_shared_from_this<LiveSession> {
  LiveSession(std::string i, SessionSecrets s, Workers& w)
      : id(std::move(i)), secrets(std::move(s)), strand(std::make_shared<Strand>(w)) {}
  const std::string id;
  const SessionSecrets secrets;
  const std::shared_ptr<Strand> strand;

  // The strand only.
  std::unique_ptr<Session> session;
  std::unique_ptr<SessionLog> journal;  // with a persistent storage
  std::exception_ptr failure;           // why the session could not be created
  std::vector<std::weak_ptr<HubClient>> clients;
  int nextClient = 1;
  bool syncScheduled = false;  // a --fsync-ms timer will sync the journal
  // After a snapshot failed, the next is not tried before snapshotNotBefore (Durability).
  Clock::time_point snapshotNotBefore{};
  std::chrono::milliseconds snapshotBackoff{0};
  HeldSplats heldSplats;       // what its splats-mode clients hold (Broadcaster)
  // One rebuild of an earlier revision at a time (HubCore::withVersion); the others wait here.
  bool rebuilding = false;
  std::deque<std::function<void()>> awaitingRebuild;

  // Presence of the clients (its own locks; see service/hub/presence_relay.hpp).
  SessionPresence presence;

  // The clients still alive: all of them, except while the hub shuts down.
  std::vector<std::shared_ptr<HubClient>> members() const {
    std::vector<std::shared_ptr<HubClient>> out;
    out.reserve(clients.size());
    for (const auto& weak : clients)
      if (auto c = weak.lock()) out.push_back(std::move(c));
    return out;
  }
  // c is still the client `clientId` of this session (it did not leave, or leave and join
  // again), so its view state belongs to this strand.
  bool hasClient(const HubClient& c, int clientId) const {
    return std::any_of(clients.begin(), clients.end(), [&](const auto& p) { return p.lock().get() == &c; }) &&
           c.clientId == clientId;
  }

  // The lease is released once (unload, shutdown); renewal, which runs off the strand so that a
  // long operation cannot let it expire, must not take it again after that. Nor may renewal ask
  // for it before the storage granted it (leaseAcquired): a session is registered before its
  // create acquires the lease on the strand, and a "no" then closed it (1011) as taken elsewhere.
  std::mutex leaseMutex;
  bool leaseAcquired = false;
  bool leaseReleased = false;
  // Written on the strand, also read under the registry's lock: atomic.
  std::atomic<bool> unloaded{false};
  // Guarded by the registry's lock: when the last client left (for the idle timeout).
  Clock::time_point emptySince = Clock::now();
  std::size_t clientCount = 0;
};

}  // namespace marzipan::service
