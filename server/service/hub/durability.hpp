// How loaded sessions stay durable through their SessionStorage (service/session_storage.hpp):
// journaling each change before it is acknowledged (and rolling back when that fails),
// snapshots, the --fsync-ms timer, lease renewal and loss, and the sweep of old sessions.
//
// Conventions:
// - persist(), rotate() and saveAndRelease() run on the session's strand; lease renewal and
//   the sweep run on timers on the workers.
// - A session whose in-memory state may be ahead of what its storage holds, or which another
//   server now owns, is closed here (SessionRegistry::closeBroken): never kept unsaved.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "protocol/cpp/rpc.hpp"

namespace marzipan::service {

struct HubCore;
struct LiveSession;

class Durability {
 public:
  explicit Durability(HubCore& hub) : hub_(hub) {}

  // Appends a change's records to the journal before it is acknowledged. When that fails the
  // session goes back to what the journal holds (the change is dropped) and this throws the
  // request's error; if even that fails the session is closed, its acknowledged state intact.
  void persist(LiveSession& s, const std::function<nlohmann::json()>& makeRecords);
  // Before an edit that changed nothing is acknowledged: nothing was written, so no write's
  // fence refused it. When the storage says this server no longer holds the lease (paused past
  // it, say), the session is closed as a fenced write would close it and this throws -32015.
  void confirmHeld(LiveSession& s);
  // A snapshot of s and a fresh journal that starts with the strokes still open, so that their
  // next dabs replay without the journal that began them.
  void rotate(LiveSession& s);
  // rotate() unless one failed within the back-off (1 s after a failure, doubling to 60 s): a
  // snapshot writes the whole volume, and one that keeps failing was tried after every change.
  // A failure is logged and the journal goes on; OwnershipLost closes the session.
  void rotateUnlessBackingOff(LiveSession& s);
  // At unload or shutdown: a last snapshot (`when` names the moment for the log), the journal
  // closed, the lease released.
  void saveAndRelease(LiveSession& s, const char* when);
  void releaseLease(LiveSession& s);

  // Renews the leases of every loaded session every renewEvery() while there are any.
  void scheduleLeaseRenewal();
  // Another server took session id: this copy goes, unsaved; its clients are closed and
  // reconnect (through the balancer) to the new holder.
  void leaseLost(const std::string& id);
  // -32015, with data.owner when the storage knows which server owns the session (etcd).
  protocol::RpcException heldElsewhere(const std::string& id, const std::string& message) const;
  // Another server owns s now: nothing here may be kept (no journal), its clients are closed
  // and find it there when they join again, and the request gets -32015 with `message`.
  [[noreturn]] void closeHeldElsewhere(LiveSession& s, const std::string& why, const std::string& message);

  // Deletes sessions at rest untouched for max_session_age, after delay and then every hour.
  void sweepOldSessions(std::chrono::milliseconds delay);

 private:
  void scheduleSync(LiveSession& s);
  HubCore& hub_;
  std::atomic<bool> leaseRenewalScheduled_{false};
};

}  // namespace marzipan::service
