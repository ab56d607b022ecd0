// Where sessions rest between loads: the hub's only view of durability. A SessionStorage keeps
// a session's secrets, its current snapshot and the journal of changes after it, and decides
// which server owns a live session (its lease). Implementations: SessionStore
// (service/session_store.hpp, files in a data directory) and makeMemoryStorage() (nothing is
// kept: sessions live while loaded). Another backend (a key-value store with leases) fits the
// same contract:
// - Ownership: acquire() before a session is created or recovered here; renew() every
//   renewEvery(); release() when it is unloaded. A lease lost (expired and taken by another
//   server, or fenced by a newer holder) is told by renew() returning false, by the handler
//   given to onLost() (from any thread, for backends that watch), and by OwnershipLost thrown
//   from the writes below. Every write of a holder carries its fencing token (the generation of
//   the lease it holds) and is refused once another holder has a newer one, so two servers
//   never both write one session.
// - Durability: a change is acknowledged only after SessionLog::append() returned; snapshot()
//   makes a new snapshot current (with a fresh log after it) atomically: the old snapshot and
//   log stay current until it returns.
// - Errors: OwnershipLost as above; StorageLimit past a bound on what one session may hold;
//   std::runtime_error naming what failed for I/O; in every case the refused write is not kept,
//   and a snapshot that failed leaves no file of its own behind (unless its outcome is unknown).
// - Threads: a session's calls come from its strand (one at a time); renew(), release(),
//   removeUntouched() and the lost handler may run concurrently with them.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "service/session.hpp"

namespace marzipan::service {

struct SessionSecrets {
  std::string token, viewToken;
};

// This server no longer owns the session: its lease expired and another server took it, or a
// newer holder fenced it. Nothing more it writes for the session is kept.
class OwnershipLost : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A change refused by the storage's bound on what one session may hold (etcd: its keys and
// bytes there); nothing of it was written. `limit` names the bound (-32004's data.limit).
class StorageLimit : public std::runtime_error {
 public:
  StorageLimit(const std::string& what, std::string limitName, std::uint64_t held, std::uint64_t bound)
      : std::runtime_error(what), limit(std::move(limitName)), value(held), max(bound) {}
  std::string limit;
  std::uint64_t value, max;  // what the session would hold with the change; the bound
};

// The open journal of a session: the changes after its current snapshot, in the record format
// of service/journal.hpp.
class SessionLog {
 public:
  virtual ~SessionLog() = default;
  // Keeps one record (durably, or within the sync interval); throws as the header says.
  virtual void append(const nlohmann::json& record) = 0;
  virtual void sync() = 0;
  // Appended records not yet synced: the owner's timer calls sync().
  virtual bool dirty() const = 0;
  // Records since the current snapshot (the hub snapshots after snapshot_every).
  virtual std::size_t records() const = 0;
  // A snapshot is due before snapshot_every: what the session holds nears the storage's bound.
  virtual bool wantsSnapshot() const { return false; }
};

struct Recovered {
  std::unique_ptr<Session> session;     // at the last revision the log acknowledged
  std::unique_ptr<SessionLog> journal;  // open for appending after it
  std::size_t replayed = 0;             // records replayed
};

class SessionStorage {
 public:
  virtual ~SessionStorage() = default;

  // False for the in-memory storage: nothing below is kept, changes need no log, and a session
  // unloaded is gone. The hub then calls none of the session methods below but acquire/release.
  virtual bool persistent() const = 0;
  // Where sessions are kept, for the log ("/var/lib/marzipan", "memory").
  virtual std::string where() const = 0;

  // --- ownership (this server's name and the lease time are the storage's) -----------------
  // False when another server holds an unexpired lease on id.
  virtual bool acquire(const std::string& id) = 0;
  // False when the lease was lost (another server took it); then the session must go.
  virtual bool renew(const std::string& id) = 0;
  // Whether this server still holds id's lease by the test its writes pass, asked before an
  // edit that changed nothing (so wrote nothing) is acknowledged: a server paused past its
  // lease must not answer "done" for a session another server now owns. Never throws; false
  // also when the storage cannot tell.
  virtual bool holds(const std::string& id) = 0;
  virtual void release(const std::string& id) = 0;
  virtual std::chrono::milliseconds renewEvery() const = 0;
  // A lease lost that the storage learns of by itself (a watch, a keep-alive failing). Set
  // before the first acquire; may be called from any thread.
  virtual void onLost(std::function<void(const std::string& id)> handler) = 0;
  // The name of the server that owns id, when the storage knows it (-32015's data.owner).
  virtual std::optional<std::string> holder(const std::string&) { return std::nullopt; }

  // --- sessions at rest --------------------------------------------------------------------
  virtual bool exists(const std::string& id) const = 0;
  virtual std::optional<SessionSecrets> secrets(const std::string& id) const = 0;
  // A new session at rest: its secrets, its first snapshot and an empty log.
  virtual std::unique_ptr<SessionLog> create(const std::string& id, const SessionSecrets& secrets,
                                             const Volume& volume) = 0;
  // A snapshot of `volume` at its revision made current, with a fresh log after it that starts
  // with `head` (the open strokes' stroke_begin records); all or nothing.
  virtual std::unique_ptr<SessionLog> snapshot(const std::string& id, const Volume& volume,
                                               const std::vector<nlohmann::json>& head = {}) = 0;
  // Keeps the bricks an undo or redo put in place for the record {"undo"/"redo": name}.
  virtual std::string saveStep(const std::string& id, std::uint64_t revision,
                               const std::vector<std::pair<Int3, BrickRef>>& bricks) = 0;
  // Keeps an uploaded .mzv for the record {"load": name}.
  virtual std::string saveUpload(const std::string& id, std::uint64_t revision, std::span<const std::uint8_t> file) = 0;
  // The session as last acknowledged: its current snapshot replayed with its log.
  virtual Recovered recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) = 0;
  // Deletes everything kept of the session (session.delete); the caller holds its lease, which
  // goes with it.
  virtual void remove(const std::string& id) = 0;
  // Deletes every session at rest untouched for maxAge, unless live(id) (loaded here) or
  // another server holds it; returns the ids deleted.
  virtual std::vector<std::string> removeUntouched(std::chrono::seconds maxAge,
                                                   const std::function<bool(const std::string&)>& live) = 0;
};

// Keeps nothing: every session lives only while loaded (tests, demos).
std::unique_ptr<SessionStorage> makeMemoryStorage();

}  // namespace marzipan::service
