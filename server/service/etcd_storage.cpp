#include "service/etcd_storage.hpp"

#include <sys/stat.h>

#include <charconv>

#include "engine/volume_file.hpp"
#include "service/journal_records.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace marzipan::service {

namespace {

// The log of one owned session: each record one fenced etcd append.
class EtcdLog final : public SessionLog {
 public:
  explicit EtcdLog(std::shared_ptr<EtcdJournal> j) : journal_(std::move(j)) {}
  void append(const json& record) override {
    try {
      journal_->append({record});
    } catch (const Fenced& e) {
      throw OwnershipLost(e.what());
    } catch (const SessionFull& e) {
      throw StorageLimit(e.what(), e.limit, e.value, e.max);
    }
    ++records_;
  }
  void sync() override {}
  bool dirty() const override { return false; }
  std::size_t records() const override { return records_; }
  bool wantsSnapshot() const override { return journal_->wantsSnapshot(); }

 private:
  std::shared_ptr<EtcdJournal> journal_;
  std::size_t records_ = 0;
};

// "PREFIX-R-T-S.EXT" -> S; nothing for another name.
std::optional<std::uint64_t> seqOfName(const std::string& name) {
  const std::size_t dot = name.rfind('.'), dash = name.rfind('-', dot);
  if (dot == std::string::npos || dash == std::string::npos || std::count(name.begin(), name.end(), '-') != 3)
    return std::nullopt;
  std::uint64_t s = 0;
  const auto [end, err] = std::from_chars(name.data() + dash + 1, name.data() + dot, s);
  if (err != std::errc() || end != name.data() + dot) return std::nullopt;
  return s;
}

}  // namespace

EtcdStorage::EtcdStorage(KeyValue& kv, fs::path dataDir, std::string address, EtcdOptions options, EtcdEvents events)
    : dir_(std::move(dataDir)),
      files_(dir_, {}, events.log, address),
      events_(events),
      owner_(kv, std::move(address), std::move(options), std::move(events)) {
  owner_.start([this] {
    // The lease is gone: every session it owned is another server's to take.
    std::vector<std::string> ids;
    std::function<void(const std::string&)> lost;
    {
      const std::lock_guard lock(mutex_);
      for (const auto& [id, j] : owned_) ids.push_back(id);
      owned_.clear();
      lost = lost_;
    }
    for (const std::string& id : ids) {
      if (events_.ownershipChanged) events_.ownershipChanged(id, false);
      if (lost) lost(id);
    }
  });
}

EtcdStorage::~EtcdStorage() { owner_.stop(); }

std::string EtcdStorage::where() const { return "etcd (sessions' files in " + dir_.string() + ")"; }

std::chrono::milliseconds EtcdStorage::renewEvery() const {
  return std::chrono::milliseconds(owner_.options().leaseTtlSeconds * 1000 / 3);
}

void EtcdStorage::onLost(std::function<void(const std::string&)> handler) {
  const std::lock_guard lock(mutex_);
  lost_ = std::move(handler);
}

std::optional<std::string> EtcdStorage::holder(const std::string& id) {
  try {
    return owner_.ownerOf(id);
  } catch (const std::exception&) {
    return std::nullopt;  // only a hint for the client
  }
}

bool EtcdStorage::acquire(const std::string& id) {
  std::shared_ptr<EtcdJournal> held;
  {
    const std::lock_guard lock(mutex_);
    if (const auto it = owned_.find(id); it != owned_.end()) held = it->second;
  }
  if (held && !held->fenced()) return true;
  if (held) {
    // Fenced while the lease was only late (a keep-alive held up past the TTL by an etcd
    // election, the lease kept alive in etcd), its owner key stays on the live lease: a session
    // loaded through it could never be edited, and no other server could claim it. The key
    // goes first (if still this journal's); when etcd cannot be reached, the next acquire
    // tries again.
    held->release();
    const std::lock_guard lock(mutex_);
    if (const auto it = owned_.find(id); it != owned_.end() && it->second == held) owned_.erase(it);
  }
  EtcdOwner::Claim c = owner_.claim(id);
  if (!c.journal) return false;
  const std::lock_guard lock(mutex_);
  owned_[id] = std::shared_ptr<EtcdJournal>(std::move(c.journal));
  return true;
}

bool EtcdStorage::renew(const std::string& id) {
  // The lease is the server's, kept alive by its own thread: renewing one session is asking
  // whether it still holds. A late lease still does (the hub closes what this says no to, and
  // etcd fences every write); a lost one is reported by the keep-alive thread as well.
  const std::lock_guard lock(mutex_);
  return owner_.leaseKept() && owned_.count(id) > 0;
}

bool EtcdStorage::holds(const std::string& id) {
  // The lease first: when it is lost, the lost handler has emptied owned_ before any new lease
  // can be granted, so a session found below is still on the lease confirmed here.
  if (!owner_.confirmLease()) return false;
  std::shared_ptr<EtcdJournal> held;
  {
    const std::lock_guard lock(mutex_);
    if (const auto it = owned_.find(id); it != owned_.end()) held = it->second;
  }
  return held && !held->fenced();
}

void EtcdStorage::release(const std::string& id) {
  std::shared_ptr<EtcdJournal> j;
  {
    const std::lock_guard lock(mutex_);
    const auto it = owned_.find(id);
    if (it == owned_.end()) return;
    j = it->second;
    owned_.erase(it);
  }
  try {
    j->release();
  } catch (const std::exception& e) {
    // The owner key goes with the lease at the latest (its TTL, or revoked at stop).
    if (events_.log) events_.log("session " + id + ": releasing it in etcd failed (" + e.what() + ")");
  }
}

std::shared_ptr<EtcdJournal> EtcdStorage::journal(const std::string& id) const {
  const std::lock_guard lock(mutex_);
  const auto it = owned_.find(id);
  if (it == owned_.end()) throw OwnershipLost("session " + id + ": this server does not own it in etcd");
  return it->second;
}

std::string EtcdStorage::fileName(const char* prefix, std::uint64_t revision, const EtcdJournal& j, const char* ext) const {
  return std::string(prefix) + "-" + std::to_string(revision) + "-" + std::to_string(j.token()) + "-" +
         std::to_string(j.nextSeq()) + ext;
}

bool EtcdStorage::exists(const std::string& id) const { return files_.exists(id); }
std::optional<SessionSecrets> EtcdStorage::secrets(const std::string& id) const { return files_.secrets(id); }

std::unique_ptr<SessionLog> EtcdStorage::create(const std::string& id, const SessionSecrets& secrets, const Volume& volume) {
  const fs::path dir = sessionDir(id);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
  ::chmod(dir.c_str(), 0700);
  auto log = snapshot(id, volume);
  // session.json last: a session exists at rest only once it can be recovered.
  const std::string meta = json{{"token", secrets.token}, {"view_token", secrets.viewToken}}.dump();
  writeFileAtomically(dir / "session.json", meta.data(), meta.size());
  syncDirectory(dir);
  return log;
}

std::unique_ptr<SessionLog> EtcdStorage::snapshot(const std::string& id, const Volume& volume, const std::vector<json>& head) {
  const auto j = journal(id);
  const std::string name = fileName("snapshot", volume.revision(), *j, ".mzv");
  const std::vector<std::uint8_t> bytes = saveVolume(volume);
  writeFileAtomically(sessionDir(id) / name, bytes.data(), bytes.size());
  // A commit that failed leaves no file: each was a whole volume, and the hub tried again after
  // every change (issue 31). When the outcome is unknown the pointer may name it: it stays, and
  // goes with the snapshot after next if it does not.
  const auto removeFile = [&] {
    std::error_code ec;
    fs::remove(sessionDir(id) / name, ec);
  };
  try {
    j->commitSnapshot(name, volume.revision(), head);
  } catch (const KvUnavailable&) {
    throw;
  } catch (const Fenced& e) {
    removeFile();
    throw OwnershipLost(e.what());
  } catch (const SessionFull& e) {
    removeFile();
    throw StorageLimit(e.what(), e.limit, e.value, e.max);
  } catch (...) {
    removeFile();
    throw;
  }
  try {
    // The pointer just written, as the journal keeps it: reading it back from etcd (with the
    // whole journal, as this did until 2026-11-29) cost a round trip and a parse of up to two
    // snapshots' worth of keys on the session's strand.
    const auto [current, previous] = j->snapshots();
    if (current) removeUnreferenced(id, *current, previous);
  } catch (const std::exception& e) {
    if (events_.log) events_.log("session " + id + ": removing files older than its snapshots failed: " + e.what());
  }
  return std::make_unique<EtcdLog>(j);
}

void EtcdStorage::removeUnreferenced(const std::string& id, const SnapshotRef& current,
                                     const std::optional<SnapshotRef>& previous) {
  const std::uint64_t keepFrom = previous ? previous->next : current.next;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(sessionDir(id), ec)) {
    const std::string name = e.path().filename().string();
    if (name == current.file || (previous && name == previous->file)) continue;
    const auto seq = seqOfName(name);
    if (!seq) continue;
    // Snapshots: only the two the pointer names are read. Step and upload files: only records
    // from the previous snapshot's SEQ on are replayed.
    const bool isSnapshot = name.starts_with("snapshot-");
    if ((isSnapshot && *seq < current.next) || (!isSnapshot && *seq < keepFrom)) fs::remove(e.path(), ec);
  }
  syncDirectory(sessionDir(id));
}

std::string EtcdStorage::saveStep(const std::string& id, std::uint64_t revision,
                                  const std::vector<std::pair<Int3, BrickRef>>& bricks) {
  const auto j = journal(id);
  const std::string name = fileName("step", revision, *j, ".bin");
  const std::vector<std::uint8_t> bytes = encodeStep(bricks);
  writeFileAtomically(sessionDir(id) / name, bytes.data(), bytes.size());
  return name;
}

std::string EtcdStorage::saveUpload(const std::string& id, std::uint64_t revision, std::span<const std::uint8_t> file) {
  const auto j = journal(id);
  const std::string name = fileName("load", revision, *j, ".mzv");
  writeFileAtomically(sessionDir(id) / name, file.data(), file.size());
  return name;
}

Recovered EtcdStorage::recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) {
  const auto j = journal(id);
  const EtcdSessionState st = owner_.read(id);
  if (!st.current) throw std::runtime_error("session " + id + ": no snapshot pointer in etcd");
  const fs::path dir = sessionDir(id);
  // The current snapshot, or the previous one when it is unreadable (its journal is kept).
  std::optional<Volume> base;
  const SnapshotRef* from = nullptr;
  for (const SnapshotRef* ref : {&*st.current, st.previous ? &*st.previous : nullptr}) {
    if (!ref || base) continue;
    try {
      base = loadVolumeFile((dir / ref->file).string());
      from = ref;
    } catch (const std::exception& e) {
      if (events_.log) events_.log("session " + id + ": snapshot " + ref->file + " is unreadable (" + e.what() + ")");
    }
  }
  if (!base) throw std::runtime_error("session " + id + ": no readable snapshot in " + dir.string());
  Recovered out;
  out.session = std::make_unique<Session>(std::move(*base), historyBytes);
  Replay replay(*out.session, [&dir](const std::string& name) { return readFile(dir / name); }, pool);
  for (const json& rec : from->head) replay.apply(rec);
  for (const JournalEntry& e : st.journal) {
    if (e.seq < from->next) continue;
    // Falling back to the previous snapshot: the current one's head re-announces the strokes
    // open at its revision, as a file journal's head does.
    if (from != &*st.current && e.seq == st.current->next)
      for (const json& rec : st.current->head) replay.apply(rec);
    for (const json& rec : e.records) {
      replay.apply(rec);
      ++out.replayed;
    }
  }
  replay.finish();
  j->resume(st);
  out.journal = std::make_unique<EtcdLog>(j);
  return out;
}

void EtcdStorage::remove(const std::string& id) {
  const auto j = journal(id);
  try {
    j->erase();
  } catch (const Fenced& e) {
    throw OwnershipLost(e.what());
  }
  {
    const std::lock_guard lock(mutex_);
    owned_.erase(id);
  }
  removeSessionFolder(sessionDir(id));
}

std::vector<std::string> EtcdStorage::removeUntouched(std::chrono::seconds maxAge,
                                                      const std::function<bool(const std::string&)>& live) {
  std::vector<std::string> removed;
  for (const std::string& id : sessionsUntouchedFor(dir_ / "sessions", maxAge, live)) {
    try {
      if (!acquire(id)) continue;
      remove(id);
      removed.push_back(id);
    } catch (const std::exception& e) {
      if (events_.log) events_.log("session " + id + ": removing it as untouched failed: " + e.what());
      release(id);
    }
  }
  return removed;
}

}  // namespace marzipan::service
