// Sessions at rest in the data directory: what makes them survive a crash, an idle unload, a
// restart, or a move to another server that shares the directory.
//
// Layout of DATA/sessions/ID/ (mode 0700: it holds the tokens):
//   session.json          {"token", "view_token"}
//   snapshot-R.mzv        the volume at revision R (engine/volume_file.hpp, CRC-checked)
//   journal-R.log         the changes after revision R (service/journal.hpp)
//   load-R.mzv            a file a volume.load brought in at revision R (named by a journal)
//   step-R.bin            the bricks an undo or redo at revision R put in place (see saveStep)
//   lease                 "OWNER EXPIRY_MS GENERATION": the server that has the session loaded
//                         (scale-out); removed when it unloads the session
//   lease.lock            flock()ed around every change of the lease (exclusive) and every
//                         write of a holder (shared); holds the last generation handed out
// The newest snapshot and the one before it are kept, with the journals from the older one
// on: a snapshot that fails its CRC falls back to the previous one and replays both journals.
// Files are written to a temporary name, fsynced and renamed, so a crash leaves the old or
// the new version, never a torn one (the journal's torn last line is dropped on reading).
// Fencing: each acquisition of a lease gets a generation one above the last; a holder's journal
// appends, snapshots and step/upload files check, under the shared lock, that the lease still
// names it with its generation, and throw OwnershipLost otherwise. A holder that stalled past
// its expiry can renew only while nobody took the lease meanwhile (renewal and takeover are
// serialized by the exclusive lock), so it never overwrites another server's fresh lease.
// Logs opened for a session whose lease this store does not hold (tools, tests) are not fenced.
// Errors: std::runtime_error naming the path (I/O), EngineError from the volume loader.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "service/journal.hpp"
#include "service/journal_records.hpp"
#include "service/session.hpp"
#include "service/session_storage.hpp"

namespace marzipan::service {

// The file implementation of SessionStorage.
class SessionStore final : public SessionStorage {
 public:
  static constexpr std::chrono::milliseconds kDefaultLeaseTtl{30'000};

  // dataDir must not be empty. owner: this server's name in leases; ttl: how long a lease
  // lasts without renewal (a crashed server's sessions wait that long).
  explicit SessionStore(std::filesystem::path dataDir, std::chrono::milliseconds syncInterval = {},
                        std::function<void(const std::string&)> log = {}, std::string owner = "marzipan",
                        std::chrono::milliseconds leaseTtl = kDefaultLeaseTtl);

  bool persistent() const override { return true; }
  std::string where() const override { return dir_.string(); }

  bool acquire(const std::string& id) override;
  bool renew(const std::string& id) override;
  // The lease file still names this server with the generation it holds (a file read).
  bool holds(const std::string& id) override;
  void release(const std::string& id) override;
  std::chrono::milliseconds renewEvery() const override { return ttl_ / 3; }
  // Files change only through this store: it learns of a loss at renewal or at a write.
  void onLost(std::function<void(const std::string&)>) override {}

  bool exists(const std::string& id) const override;
  std::optional<SessionSecrets> secrets(const std::string& id) const override;
  std::unique_ptr<SessionLog> create(const std::string& id, const SessionSecrets& secrets, const Volume& volume) override;
  // Files older than the previous snapshot are deleted. The new journal is written with its
  // head in one atomic file: the rotation is complete or did not happen (then this throws and
  // the old snapshot and journal stay the ones to append to).
  std::unique_ptr<SessionLog> snapshot(const std::string& id, const Volume& volume,
                                       const std::vector<nlohmann::json>& head = {}) override;
  // "step-R.bin": "MZBK", u32 count, per brick i32 x y z, u8 0 outside / 1 inside / 2 data +
  // 512 f32, then the CRC-32 of all before it; little-endian.
  std::string saveStep(const std::string& id, std::uint64_t revision,
                       const std::vector<std::pair<Int3, BrickRef>>& bricks) override;
  std::string saveUpload(const std::string& id, std::uint64_t revision, std::span<const std::uint8_t> file) override;
  // The newest readable snapshot plus its journals.
  Recovered recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) override;
  void remove(const std::string& id) override;
  std::vector<std::string> removeUntouched(std::chrono::seconds maxAge,
                                           const std::function<bool(const std::string&)>& live) override;

  // The lease of id for `owner`, below the interface (tests, tools): its generation, or nothing
  // when another owner holds an unexpired one. `held`: the generation the caller holds, to
  // renew it (nothing when the lease was taken meanwhile, even if it expired since); without
  // it a new generation is taken (a server restarted with the same name takes its own lease
  // back at once).
  std::optional<std::uint64_t> takeLease(const std::string& id, const std::string& owner, std::chrono::milliseconds ttl,
                                         std::optional<std::uint64_t> held = std::nullopt) const;
  // Removes the lease if `owner` holds it (with generation `held`, when given).
  void releaseLease(const std::string& id, const std::string& owner,
                    std::optional<std::uint64_t> held = std::nullopt) const;

 private:
  std::filesystem::path sessionDir(const std::string& id) const;
  // The generation this store holds for id, if any.
  std::optional<std::uint64_t> held(const std::string& id) const;
  // Throws OwnershipLost unless this store still holds id's lease (when it took one).
  void checkFence(const std::string& id) const;
  std::unique_ptr<SessionLog> openLog(const std::string& id, const std::filesystem::path& journal) const;
  void warn(const std::string& line) const {
    if (log_) log_(line);
  }
  std::filesystem::path dir_;
  std::chrono::milliseconds syncInterval_;
  std::function<void(const std::string&)> log_;
  std::string owner_;
  std::chrono::milliseconds ttl_;
  mutable std::mutex mutex_;                    // guards leases_
  std::map<std::string, std::uint64_t> leases_;  // the generations this store holds, by session id
};

// Writes bytes to path through path + ".tmp", fsync and rename.
void writeFileAtomically(const std::filesystem::path& path, const void* data, std::size_t size);
// fsyncs a directory (after a rename or an unlink in it); a directory that cannot be opened is
// left alone.
void syncDirectory(const std::filesystem::path& dir);
// The session folders under `sessions` (folder name = session id) not live(id) whose every
// file was last written more than maxAge ago.
std::vector<std::string> sessionsUntouchedFor(const std::filesystem::path& sessions, std::chrono::seconds maxAge,
                                              const std::function<bool(const std::string&)>& live);
// Removes a session's folder and syncs its parent; throws std::runtime_error "cannot remove PATH: why".
void removeSessionFolder(const std::filesystem::path& folder);
// The whole file; throws std::runtime_error "cannot read PATH".
std::vector<std::uint8_t> readFile(const std::filesystem::path& path);

}  // namespace marzipan::service
