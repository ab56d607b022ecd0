// Sessions owned through etcd (or any service/key_value.hpp store): one owner per session,
// fenced, and a journal that no stale owner can write.
//
// Keys, under options.prefix (default "marzipan/"), for session ID:
//   sessions/ID/owner        the owning server's address (what -32015 tells clients), attached
//                            to that server's lease; its createRevision is the FENCING TOKEN
//   sessions/ID/journal/SEQ  one acknowledged change: {"records":[...],"token":T} (records as in
//                            service/journal.hpp), or part of a snapshot's head: {"head":[...],
//                            "token":T}; SEQ is 16 lower-case hex digits, from 0, so that key
//                            order is sequence order; written only if absent
//   sessions/ID/snapshot     the pointer readers trust: {"current":{"file","revision",
//                            "head_from","next"},"previous":{...}}: a snapshot file (never-reused
//                            name, written by the caller beside session.json), its head (the
//                            records replay starts with: the open strokes', with their
//                            memories) in the journal keys [head_from, next), and the first SEQ
//                            of the changes after it. A pointer written before 2026-11-29 holds
//                            its head itself ("head":[...]), twice over with the previous one's:
//                            read as such.
// A snapshot is committed in two steps: its head is appended to the journal (as few keys as
// fit maxChangeBytes, each written once; replay skips head keys no pointer names, a failed
// commit's), then one fenced transaction moves the pointer and deletes the journal keys before
// the previous snapshot's head.
// What one session holds (its journal keys, pointer and owner key, counted as key and value
// bytes) is bounded by options.maxSessionKeys and maxSessionBytes: an append past either is
// refused with SessionFull before anything is written, and so is a snapshot whose head would
// leave the session over them once the pointer has moved (one without a head always goes: it
// only frees). Between a head's append and the pointer's move the session holds that head on
// top, and a head whose commit failed stays until the snapshot after next deletes it.
// Ownership: each server holds one lease (TTL options.leaseTtl, kept alive every third of it by
// a thread of its own, revoked by stop()). claim() creates the owner key in a transaction only
// if it is absent. Every write of an owner compares the owner key's createRevision with its
// token: after a lease expiry the key is gone (or re-created by another server with a higher
// revision), so a paused owner that wakes up is refused by etcd itself, whatever its clock says.
// The lease is lost when a keep-alive answers "expired" or none succeeded for a whole TTL: the
// owner then refuses appends locally at once (Fenced) and `lost` is called once. A lease only
// late (not renewed within its TTL, not yet found lost) is not refused locally: appends go to
// etcd, whose fence decides; what writes nothing asks confirmLease().
// Appends from all sessions of a server are grouped: while one transaction is in flight the
// next ones queue and go together as one transaction (bounded by etcd's --max-txn-ops and
// --max-request-bytes), so strokes keep up without waiting for a timer.
// Errors: Fenced (not, or no longer, the owner: nothing was written), KvRefused (too large for
// etcd, quota exceeded, or SessionFull: nothing was written), KvUnavailable (no member answered: the outcome is
// unknown and the journal refuses further appends until the session is read back).
// Thread-safety: EtcdOwner and its journals may be used from any thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/key_value.hpp"

namespace marzipan::service {

struct Fenced : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A write refused because the session would hold more than options.maxSessionKeys or
// maxSessionBytes in etcd; nothing was written.
struct SessionFull : KvRefused {
  SessionFull(const std::string& what, std::string limitName, std::size_t held, std::size_t bound)
      : KvRefused(what), limit(std::move(limitName)), value(held), max(bound) {}
  std::string limit;  // "max_session_etcd_keys" or "max_session_etcd_bytes"
  std::size_t value;  // what the session would hold with the write
  std::size_t max;
};

// What the metrics hear (any thread; may be empty).
struct EtcdEvents {
  std::function<void(const std::string& id, bool gained)> ownershipChanged;
  std::function<void(const std::string& id)> fencedRejection;
  std::function<void(double seconds, std::size_t changes)> appended;  // one group transaction
  std::function<void(const std::string&)> log;
};

struct EtcdOptions {
  std::string prefix = "marzipan/";
  std::int64_t leaseTtlSeconds = 5;
  // etcd's defaults: --max-txn-ops 128 (per branch and for compares), --max-request-bytes
  // 1.5 MiB. The gateway base64-encodes keys and values (4/3) inside JSON; one change beyond
  // maxChangeBytes is refused (KvRefused) before it is sent.
  std::size_t maxTxnOps = 128;
  std::size_t maxRequestBytes = 1'572'864;
  std::size_t maxChangeBytes = 1'000'000;
  // What one session may hold in etcd (see the header): 128 sessions at these bounds fill etcd's
  // default 2 GiB quota. The keys allow two snapshots' journals at the hub's snapshot_every
  // (2000) with room to spare; the bytes two snapshots' heads of a dozen strokes with full
  // memories (4096 dab images with normals: ~490 KB as JSON each) and the changes between.
  std::size_t maxSessionKeys = 10'000;
  std::size_t maxSessionBytes = std::size_t(16) << 20;
};

// A snapshot the pointer names.
struct SnapshotRef {
  std::string file;
  std::uint64_t revision = 0;
  std::uint64_t headFrom = 0;  // its head's journal keys: [headFrom, next)
  std::uint64_t next = 0;      // the first journal SEQ after it
  // Replayed before the journal from `next`: the records of its head keys, as EtcdOwner::read
  // found them (an EtcdJournal's own refs leave them out), or of an older pointer's own head.
  std::vector<nlohmann::json> head;
};

// A change read back from the journal.
struct JournalEntry {
  std::uint64_t seq = 0;
  std::int64_t token = 0;
  std::vector<nlohmann::json> records;
};

// What is at rest for a session: the pointer and the journal from the previous snapshot on.
struct EtcdSessionState {
  std::optional<SnapshotRef> current, previous;
  std::vector<JournalEntry> journal;  // the changes, in SEQ order (head keys left out)
  std::uint64_t next = 0;             // the SEQ after the last journal key
  // Every journal key kept (changes and heads, from the previous snapshot's head on, contiguous):
  // SEQ -> bytes of key and value; and the pointer key's bytes.
  std::map<std::uint64_t, std::size_t> keys;
  std::size_t pointerBytes = 0;
};

class EtcdOwner;

// One owned session's journal. Created by EtcdOwner::claim.
class EtcdJournal {
 public:
  // Appends one change (its records) under the next SEQ; returns once etcd has it.
  void append(const std::vector<nlohmann::json>& records);
  // Makes `file` current (it must be complete and synced): appends `head` (the records replay
  // starts with) to the journal, then moves the pointer and deletes the journal keys before the
  // previous snapshot's head, in one fenced transaction. Until the pointer has moved nothing
  // names the head keys. Throws KvRefused (nothing written) when one head record is over
  // maxChangeBytes, SessionFull as the header says.
  void commitSnapshot(const std::string& file, std::uint64_t revision, const std::vector<nlohmann::json>& head = {});
  // What the session holds beyond its current snapshot (its changes, a failed commit's head)
  // is a quarter of a bound: time for a snapshot, which deletes what came before the previous.
  // Snapshotting at a quarter keeps a session with heads under a quarter each within its bounds.
  bool wantsSnapshot() const;
  // What the session holds in etcd now: keys, and bytes of keys and values.
  std::pair<std::size_t, std::size_t> held() const;
  // After a read-back (an append's outcome was unknown): appends continue after what `state`
  // holds. A fenced journal stays fenced.
  void resume(const EtcdSessionState& state);
  std::uint64_t nextSeq() const;
  // The snapshots the pointer names, as this journal last wrote or read it: what a reader of the
  // pointer would find while this journal owns the session, without a round trip.
  std::pair<std::optional<SnapshotRef>, std::optional<SnapshotRef>> snapshots() const;
  // Whether it refuses every append for good (fenced by etcd, or while the lease was not live).
  bool fenced() const;
  std::int64_t token() const { return token_; }
  const std::string& id() const { return id_; }
  // Deletes the owner key (if still this token's): another server may take the session at once.
  void release();
  // Deletes every key of the session, the owner key last of all (fenced): session.delete.
  void erase();

 private:
  friend class EtcdOwner;
  EtcdJournal(EtcdOwner& owner, std::string id, std::int64_t token, EtcdSessionState state);
  EtcdOwner& owner_;
  const std::string id_;
  const std::int64_t token_;
  mutable std::mutex mutex_;
  std::uint64_t next_ = 0;
  // unknown: an append's outcome is unknown (read the session back first); fenced: another
  // server owns the session. Either way nothing more is written through this journal.
  enum class State { open, unknown, fenced };
  State state_ = State::open;
  void refuseIfBroken() const;
  // The rest with mutex_ held. Appends one journal value under next_ (bytes: of key and value).
  void submitLocked(std::string value, std::size_t bytes);
  std::pair<std::size_t, std::size_t> heldLocked() const;
  // Throws SessionFull when holding `keys` keys and `bytes` bytes would pass a bound.
  void checkBounds(std::size_t keys, std::size_t bytes) const;
  std::optional<SnapshotRef> current_, previous_;  // without the records of head keys
  // What the session holds: the journal keys kept (SEQ -> bytes), their sum, the pointer's bytes,
  // the owner key's.
  std::map<std::uint64_t, std::size_t> keys_;
  std::size_t keyBytes_ = 0, pointerBytes_ = 0;
  const std::size_t ownerBytes_;
};

class EtcdOwner {
 public:
  // `address`: how clients reach this server (host:port), stored in the owner keys.
  EtcdOwner(KeyValue& kv, std::string address, EtcdOptions options = {}, EtcdEvents events = {});
  ~EtcdOwner();  // stop()
  EtcdOwner(const EtcdOwner&) = delete;
  EtcdOwner& operator=(const EtcdOwner&) = delete;

  // Grants the lease and starts keeping it alive; `lost` is called (from the keep-alive thread)
  // each time it is lost, and a new lease is asked for at once. Throws KvUnavailable when etcd
  // cannot be reached.
  void start(std::function<void()> lost = {});
  // Revokes the lease (every session it owns is free at once) and stops the keep-alive.
  void stop();
  bool leaseHeld() const;
  // Not (yet) found lost by the keep-alive thread: it may be late. What the fence-less local
  // decisions that must not close a session on lateness alone ask (appends, the hub's renewal).
  bool leaseKept() const;
  // leaseHeld(), but a lease not renewed within its TTL is first renewed (waiting up to
  // kLeaseWait, as claim() does): it may only be late (an etcd election holding the keep-alive
  // up, etcd keeping the lease), or gone (etcd answers "expired": false at once).
  bool confirmLease();

  struct Claim {
    std::unique_ptr<EtcdJournal> journal;  // set when this server owns the session now
    EtcdSessionState state;                // what is at rest (when owned)
    std::string owner;                     // the other owner's address (when not)
  };
  // Takes the session if no one owns it; reads back its state when taken (when that read
  // fails, the owner key just written is deleted again, if still this claim's, and the error
  // thrown: the session stays free, here as elsewhere). Without a live lease
  // (lost, or not renewed within its TTL, e.g. after the process was stopped) it has the
  // keep-alive thread renew or replace it and waits up to kLeaseWait; then KvUnavailable.
  Claim claim(const std::string& id);
  // The address of the session's owner, if any.
  std::optional<std::string> ownerOf(const std::string& id);
  // What is at rest, read without owning (tests, tools).
  EtcdSessionState read(const std::string& id);

  const std::string& address() const { return address_; }
  const EtcdOptions& options() const { return options_; }

  std::string ownerKey(const std::string& id) const;
  std::string journalKey(const std::string& id, std::uint64_t seq) const;
  std::string pointerKey(const std::string& id) const;

 private:
  friend class EtcdJournal;
  struct Pending;
  // Group commit: blocks until this change's transaction has an outcome.
  void submit(EtcdJournal& j, std::uint64_t seq, std::string value);
  void runGroup(std::vector<std::shared_ptr<Pending>> group);
  void keepAlive();
  void loseLease(const std::string& why);
  void fenced(const std::string& id);

  KeyValue& kv_;
  const std::string address_;
  const EtcdOptions options_;
  const EtcdEvents events_;

  static constexpr std::chrono::milliseconds kLeaseWait{1500};
  bool liveLease() const;  // with mutex_ held

  mutable std::mutex mutex_;  // guards everything below
  std::condition_variable wake_;     // the keep-alive thread: stop, or renew now
  std::condition_variable renewed_;  // claim(), confirmLease(): a lease was renewed, granted or lost
  bool renewNow_ = false;
  std::int64_t lease_ = 0;
  bool held_ = false, stopping_ = false;
  std::chrono::steady_clock::time_point lastRenewed_;
  std::function<void()> lost_;
  std::thread keeper_;
  std::deque<std::shared_ptr<Pending>> queue_;
  bool committing_ = false;  // a caller is sending groups
};

}  // namespace marzipan::service
