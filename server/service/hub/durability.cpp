#include "service/hub/durability.hpp"

#include <algorithm>

#include "service/hub/core.hpp"
#include "service/journal_records.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;

RpcException Durability::heldElsewhere(const std::string& id, const std::string& message) const {
  const std::optional<std::string> owner = hub_.store->holder(id);
  return RpcException(RpcCode::HeldElsewhere, message, owner ? json{{"owner", *owner}} : json());
}

void Durability::persist(LiveSession& s, const std::function<json()>& makeRecords) {
  const auto& store = hub_.store;
  if (!s.journal) {
    // With a data directory a change is acknowledged only once journaled.
    if (store->persistent()) throw RpcException(RpcCode::Busy, "the server is shutting down; the change was not kept");
    return;
  }
  try {
    // Inside the try: making the records may write files (an undo's bricks, an upload).
    const json records = makeRecords();
    if (records.is_array())
      for (const json& r : records) s.journal->append(r);
    else
      s.journal->append(records);
  } catch (const OwnershipLost& e) {
    closeHeldElsewhere(s, e.what(), "another server took over this session; the change was not kept. Join it again");
  } catch (const std::exception& e) {
    hub_.log("session " + s.id + ": " + e.what() + "; rolling back to the journal");
    s.journal.reset();
    try {
      Recovered rec = store->recover(s.id, hub_.limits().historyBytes, hub_.pool);
      s.session = std::move(rec.session);
      s.heldSplats.clear();  // its clients hold what they were sent of the session rolled back
      s.journal = std::move(rec.journal);
    } catch (const std::exception& again) {
      hub_.log("session " + s.id + ": cannot reopen its journal (" + again.what() + "); closing it");
      hub_.registry.closeBroken(s);
    }
    for (const auto& c : s.members()) c->stroke = 0;
    if (const auto* full = dynamic_cast<const StorageLimit*>(&e)) {
      // Room comes back with a snapshot, which drops what came before the previous one; the roll
      // back ended the open strokes, so it has no head to hold.
      if (s.journal) rotateUnlessBackingOff(s);
      throw RpcException(RpcCode::LimitExceeded,
                         std::string("the change was not kept: ") + e.what() + ". The session is as it was; try again later",
                         {{"limit", full->limit}, {"value", full->value}, {"max", full->max}});
    }
    throw RpcException(RpcCode::Internal, std::string("the change could not be stored (") + e.what() +
                                              "); it was not kept. The session is as it was");
  }
  if (s.journal->dirty()) scheduleSync(s);
  if (s.journal->records() >= hub_.options.snapshotEvery || s.journal->wantsSnapshot()) rotateUnlessBackingOff(s);
}

void Durability::rotateUnlessBackingOff(LiveSession& s) {
  constexpr std::chrono::milliseconds kFirstBackoff{1000}, kLongestBackoff{60'000};
  const auto now = Clock::now();
  if (now < s.snapshotNotBefore) return;
  try {
    rotate(s);
    s.snapshotBackoff = {};
  } catch (const OwnershipLost& e) {
    // The change was journaled while the lease was still this server's: acknowledged, but
    // the session goes.
    hub_.log("session " + s.id + ": " + e.what() + "; closing it here");
    s.journal.reset();
    hub_.registry.closeBroken(s);
  } catch (const std::exception& e) {
    s.snapshotBackoff = std::clamp(s.snapshotBackoff * 2, kFirstBackoff, kLongestBackoff);
    s.snapshotNotBefore = now + s.snapshotBackoff;
    hub_.log("session " + s.id + ": snapshot failed (" + e.what() + "); the journal goes on, next try in " +
             std::to_string(s.snapshotBackoff.count() / 1000) + " s at the earliest");
  }
}

void Durability::confirmHeld(LiveSession& s) {
  if (!s.journal || hub_.store->holds(s.id)) return;
  closeHeldElsewhere(s, "this server no longer holds its lease",
                     "this server no longer holds the session; the edit changed nothing. Join it again");
}

void Durability::closeHeldElsewhere(LiveSession& s, const std::string& why, const std::string& message) {
  hub_.log("session " + s.id + ": " + why + "; closing it here");
  s.journal.reset();
  hub_.registry.closeBroken(s);
  throw heldElsewhere(s.id, message);
}

void Durability::rotate(LiveSession& s) {
  // An open warp stroke is announced as going on from the snapshot's volume (its base is not
  // saved), and once the snapshot is there it does so here too (Session::rebaseWarps).
  std::vector<json> head;
  for (auto [id, st] : s.session->openStrokeList()) {
    if (st.warp) rebaseWarp(*st.warp);
    head.push_back(strokeBeginRecord(id, st));
  }
  s.journal = hub_.store->snapshot(s.id, s.session->volume(), head);
  s.session->rebaseWarps();
}

void Durability::saveAndRelease(LiveSession& s, const char* when) {
  try {
    s.journal = hub_.store->snapshot(s.id, s.session->volume());
  } catch (const std::exception& e) {
    // The journal holds every acknowledged change: the session is safe without the snapshot.
    hub_.log("session " + s.id + ": snapshot at " + when + " failed (the journal has every change): " + e.what());
  }
  s.journal.reset();
  releaseLease(s);
}

// With --fsync-ms N, records that did not sync on append are synced by a timer within N ms (an
// append syncs only when N ms passed since the last sync).
void Durability::scheduleSync(LiveSession& s) {
  if (s.syncScheduled) return;
  s.syncScheduled = true;
  const std::weak_ptr<LiveSession> weak = hub_.registry.current(s);
  hub_.workers.postAfter(hub_.options.fsyncInterval, [self = hub_.shared_from_this(), weak] {
    const auto live = weak.lock();
    if (!live) return;
    live->strand->post([self, live] {
      live->syncScheduled = false;
      if (!live->journal || !live->journal->dirty()) return;
      try {
        live->journal->sync();
        if (self->options.events.journalSynced) self->options.events.journalSynced();
      } catch (const std::exception& e) {
        self->log("session " + live->id + ": " + e.what());
      }
    });
  });
}

void Durability::releaseLease(LiveSession& s) {
  const std::lock_guard lease(s.leaseMutex);
  if (std::exchange(s.leaseReleased, true)) return;
  hub_.store->release(s.id);
}

void Durability::scheduleLeaseRenewal() {
  if (!hub_.store->persistent() || leaseRenewalScheduled_.exchange(true)) return;
  hub_.workers.postAfter(hub_.store->renewEvery(), [self = hub_.shared_from_this()] {
    Durability& d = self->durability;
    d.leaseRenewalScheduled_ = false;
    const std::vector<std::shared_ptr<LiveSession>> lives = self->registry.all();
    for (const auto& renewed : lives) {
      bool held = false;
      try {
        const std::lock_guard lease(renewed->leaseMutex);
        if (renewed->leaseReleased) continue;  // unloaded meanwhile: renewing would take it back
        if (!renewed->leaseAcquired) continue;  // still being created: not this server's yet
        held = self->store->renew(renewed->id);
      } catch (const std::exception& e) {
        self->log("session " + renewed->id + ": renewing its lease failed: " + e.what());
        continue;  // a storage hiccup; the lease still has most of its time
      }
      if (!held) d.leaseLost(renewed->id);
    }
    if (!lives.empty()) d.scheduleLeaseRenewal();
  });
}

void Durability::leaseLost(const std::string& id) {
  const std::shared_ptr<LiveSession> live = hub_.registry.find(id);
  if (!live) return;
  hub_.log("session " + id + ": another server took its lease; closing it here");
  live->strand->post([self = hub_.shared_from_this(), live] {
    if (live->unloaded) return;
    live->journal.reset();
    self->registry.closeBroken(*live);
  });
}

void Durability::sweepOldSessions(std::chrono::milliseconds delay) {
  if (!hub_.store->persistent()) return;
  hub_.workers.postAfter(delay, [self = hub_.shared_from_this()] {
    const auto maxAge = self->limits().maxSessionAge;
    try {
      const auto removed = self->store->removeUntouched(
          std::chrono::duration_cast<std::chrono::seconds>(maxAge),
          [&](const std::string& id) { return self->registry.find(id) != nullptr; });
      for (const std::string& id : removed)
        self->log("session " + id + ": untouched for " + std::to_string(maxAge.count() / 24) + " days, deleted");
    } catch (const std::exception& e) {
      self->log(std::string("sweeping old sessions failed: ") + e.what());
    }
    self->durability.sweepOldSessions(std::chrono::hours(1));
  });
}

}  // namespace marzipan::service
