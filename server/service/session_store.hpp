// Sessions at rest in the data directory: what makes them survive a crash, an idle unload, a
// restart, or a move to another server that shares the directory.
//
// Layout of DATA/sessions/ID/ (mode 0700: it holds the tokens):
//   session.json          {"token", "view_token"}
//   snapshot-R.mzv        the volume at revision R (engine/volume_file.hpp, CRC-checked)
//   journal-R.log         the changes after revision R (service/journal.hpp)
//   load-R.mzv            a file a volume.load brought in at revision R (named by a journal)
//   step-R.bin            the bricks an undo or redo at revision R put in place (see saveStep)
//   lease                 "OWNER EXPIRY_MS": the server that has the session loaded (scale-out)
// The newest snapshot and the one before it are kept, with the journals from the older one
// on: a snapshot that fails its CRC falls back to the previous one and replays both journals.
// Files are written to a temporary name, fsynced and renamed, so a crash leaves the old or
// the new version, never a torn one (the journal's torn last line is dropped on reading).
// Errors: std::runtime_error naming the path (I/O), EngineError from the volume loader.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "service/journal.hpp"
#include "service/session.hpp"

namespace marzipan::service {

// The journal record of a stroke's start (journal.hpp): tool, radius, strength, symmetry,
// accumulate, and what it applied so far (its memory), which recovery reads back. The hub writes
// it at stroke.begin and at the head of every new journal for the strokes still open.
nlohmann::json strokeBeginRecord(StrokeId id, const Session::StrokeParams& st);

struct SessionSecrets {
  std::string token, viewToken;
};

struct Recovered {
  std::unique_ptr<Session> session;  // at the last revision the journal acknowledged
  std::unique_ptr<Journal> journal;  // open for appending after it
  std::size_t replayed = 0;          // records replayed
};

class SessionStore {
 public:
  // An empty dataDir disables the store (nothing is written, nothing exists).
  SessionStore(std::filesystem::path dataDir, std::chrono::milliseconds syncInterval = {},
               std::function<void(const std::string&)> log = {});

  bool enabled() const { return !dir_.empty(); }
  bool exists(const std::string& id) const;
  std::optional<SessionSecrets> secrets(const std::string& id) const;

  // A new session at rest: session.json, its first snapshot and an empty journal.
  std::unique_ptr<Journal> create(const std::string& id, const SessionSecrets& secrets, const Volume& volume) const;
  // A snapshot of `volume` at its revision and a fresh journal after it; files older than the
  // previous snapshot are deleted.
  // `head`: the records the new journal starts with (the open strokes' stroke_begin), written
  // with it in one atomic file: the rotation is complete or did not happen (then this throws
  // and the old snapshot and journal stay the ones to append to).
  std::unique_ptr<Journal> snapshot(const std::string& id, const Volume& volume,
                                    const std::vector<nlohmann::json>& head = {}) const;
  // Keeps the bricks an undo or redo put in place, for the journal record {"undo"/"redo": name};
  // returns the name ("step-R.bin": "MZBK", u32 count, per brick i32 x y z, u8 0 outside /
  // 1 inside / 2 data + 512 f32, then the CRC-32 of all before it; little-endian).
  std::string saveStep(const std::string& id, std::uint64_t revision,
                       const std::vector<std::pair<Int3, BrickRef>>& bricks) const;
  // Keeps an uploaded .mzv for the journal record {"load": name}; returns the name.
  std::string saveUpload(const std::string& id, std::uint64_t revision, std::span<const std::uint8_t> file) const;
  // The session as last acknowledged: the newest readable snapshot plus its journals.
  Recovered recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) const;

  // The lease: false when another owner holds an unexpired one. Taking it again renews it.
  bool takeLease(const std::string& id, const std::string& owner, std::chrono::milliseconds ttl) const;
  void releaseLease(const std::string& id, const std::string& owner) const;

  // Deletes every session at rest whose files all are older than maxAge, unless live(id) says
  // it is loaded here or another owner holds its lease; returns the ids deleted.
  std::vector<std::string> removeUntouched(std::chrono::seconds maxAge, const std::string& owner,
                                           std::chrono::milliseconds ttl,
                                           const std::function<bool(const std::string&)>& live) const;

 private:
  std::filesystem::path sessionDir(const std::string& id) const;
  void warn(const std::string& line) const {
    if (log_) log_(line);
  }
  std::filesystem::path dir_;
  std::chrono::milliseconds syncInterval_;
  std::function<void(const std::string&)> log_;
};

// Writes bytes to path through path + ".tmp", fsync and rename.
void writeFileAtomically(const std::filesystem::path& path, const void* data, std::size_t size);

}  // namespace marzipan::service
