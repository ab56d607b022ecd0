// SessionStore (see session_store.hpp), with the replay of journal records into a Session.
#include "service/session_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/little_endian.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/journal_records.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace marzipan::service {

void syncDirectory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

std::vector<std::string> sessionsUntouchedFor(const fs::path& sessions, std::chrono::seconds maxAge,
                                              const std::function<bool(const std::string&)>& live) {
  std::vector<std::string> ids;
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (const fs::directory_entry& entry : fs::directory_iterator(sessions, ec)) {
    std::string id = entry.path().filename().string();
    if (!entry.is_directory(ec) || live(id)) continue;
    bool old = true;
    for (const fs::directory_entry& file : fs::directory_iterator(entry.path(), ec))
      if (now - file.last_write_time(ec) < maxAge) old = false;
    if (old) ids.push_back(std::move(id));
  }
  return ids;
}

void removeSessionFolder(const fs::path& folder) {
  std::error_code ec;
  fs::remove_all(folder, ec);
  if (ec) throw std::runtime_error("cannot remove " + folder.string() + ": " + ec.message());
  syncDirectory(folder.parent_path());
}

std::vector<std::uint8_t> readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  return std::vector<std::uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeFileAtomically(const fs::path& path, const void* data, std::size_t size) {
  const fs::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  try {
    writeAll(fd, {static_cast<const char*>(data), size}, tmp);
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot flush " + tmp.string() + ": " + std::strerror(e));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot rename " + tmp.string() + ": " + std::strerror(e));
  }
  // The rename itself is durable only once the directory is.
  syncDirectory(path.parent_path());
}

namespace {

// Revisions of the files "PREFIX-R.EXT" in dir, ascending.
std::vector<std::uint64_t> revisions(const fs::path& dir, std::string_view prefix, std::string_view ext) {
  std::vector<std::uint64_t> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= prefix.size() + ext.size() || name.compare(0, prefix.size(), prefix) != 0 ||
        name.compare(name.size() - ext.size(), ext.size(), ext) != 0)
      continue;
    std::uint64_t r = 0;
    const char* b = name.data() + prefix.size();
    const char* e = name.data() + name.size() - ext.size();
    const auto [end, err] = std::from_chars(b, e, r);
    if (err == std::errc() && end == e) out.push_back(r);
  }
  std::sort(out.begin(), out.end());
  return out;
}

fs::path snapshotPath(const fs::path& dir, std::uint64_t r) { return dir / ("snapshot-" + std::to_string(r) + ".mzv"); }
fs::path journalPath(const fs::path& dir, std::uint64_t r) { return dir / ("journal-" + std::to_string(r) + ".log"); }

long long nowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

struct Lease {
  std::string owner;  // empty: none
  long long expiresMs = 0;
  std::uint64_t generation = 0;
};

Lease readLease(const fs::path& path) {
  std::ifstream in(path);
  Lease l;
  if (!(in >> l.owner >> l.expiresMs)) return {};
  if (!(in >> l.generation)) l.generation = 0;  // written before generations existed
  return l;
}

// flock() on DIR/lease.lock for as long as it lives: exclusive to change the lease, shared to
// write as its holder. The file also keeps the last generation handed out, which outlives the
// lease file (removed at release) so that generations only grow.
class LeaseLock {
 public:
  LeaseLock(const fs::path& dir, bool exclusive) : path_(dir / "lease.lock") {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (fd_ < 0) throw std::runtime_error("cannot open " + path_.string() + ": " + std::strerror(errno));
    while (::flock(fd_, exclusive ? LOCK_EX : LOCK_SH) != 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd_);
      throw std::runtime_error("cannot lock " + path_.string() + ": " + std::strerror(e));
    }
  }
  ~LeaseLock() { ::close(fd_); }
  LeaseLock(const LeaseLock&) = delete;
  LeaseLock& operator=(const LeaseLock&) = delete;

  std::uint64_t lastGeneration() const {
    char text[32] = {};
    const ssize_t n = ::pread(fd_, text, sizeof text - 1, 0);
    std::uint64_t g = 0;
    if (n > 0) std::from_chars(text, text + n, g);
    return g;
  }
  void setLastGeneration(std::uint64_t g) const {
    const std::string text = std::to_string(g) + "\n";
    if (::pwrite(fd_, text.data(), text.size(), 0) != ssize_t(text.size()) || ::ftruncate(fd_, off_t(text.size())) != 0 ||
        ::fsync(fd_) != 0)
      throw std::runtime_error("cannot write " + path_.string() + ": " + std::strerror(errno));
  }

 private:
  fs::path path_;
  int fd_ = -1;
};

// What a holder's writes check: the lease still names `owner` with `generation`.
struct Fence {
  fs::path dir;
  std::string id, owner;
  std::uint64_t generation = 0;

  // The shared lock, held while the caller writes; throws OwnershipLost when fenced off.
  std::unique_ptr<LeaseLock> hold() const {
    auto lock = std::make_unique<LeaseLock>(dir, false);
    const Lease l = readLease(dir / "lease");
    if (l.owner != owner || l.generation != generation)
      throw OwnershipLost("session " + id + ": this server's lease (generation " + std::to_string(generation) +
                          ") is gone" + (l.owner.empty() ? std::string() : ", held by " + l.owner + " (generation " +
                                                                                  std::to_string(l.generation) + ")"));
    return lock;
  }
};

class FileLog final : public SessionLog {
 public:
  FileLog(const fs::path& path, std::chrono::milliseconds syncInterval, std::optional<Fence> fence)
      : journal_(path, syncInterval), fence_(std::move(fence)) {}
  void append(const json& record) override {
    const auto lock = fence_ ? fence_->hold() : nullptr;
    journal_.append(record);
  }
  void sync() override { journal_.sync(); }
  bool dirty() const override { return journal_.dirty(); }
  std::size_t records() const override { return journal_.records(); }

 private:
  Journal journal_;
  std::optional<Fence> fence_;
};

}  // namespace

SessionStore::SessionStore(fs::path dataDir, std::chrono::milliseconds syncInterval,
                           std::function<void(const std::string&)> log, std::string owner,
                           std::chrono::milliseconds leaseTtl)
    : dir_(std::move(dataDir)),
      syncInterval_(syncInterval),
      log_(std::move(log)),
      owner_(std::move(owner)),
      ttl_(leaseTtl) {
  if (dir_.empty()) throw std::invalid_argument("SessionStore needs a data directory");
  std::error_code ec;
  fs::create_directories(dir_ / "sessions", ec);
  if (ec) throw std::runtime_error("cannot create " + (dir_ / "sessions").string() + ": " + ec.message());
  ::chmod((dir_ / "sessions").c_str(), 0700);
}

fs::path SessionStore::sessionDir(const std::string& id) const { return dir_ / "sessions" / id; }

std::optional<std::uint64_t> SessionStore::held(const std::string& id) const {
  const std::lock_guard lock(mutex_);
  const auto it = leases_.find(id);
  return it == leases_.end() ? std::nullopt : std::optional(it->second);
}

void SessionStore::checkFence(const std::string& id) const {
  if (const auto g = held(id)) Fence{sessionDir(id), id, owner_, *g}.hold();
}

std::unique_ptr<SessionLog> SessionStore::openLog(const std::string& id, const fs::path& journal) const {
  std::optional<Fence> fence;
  if (const auto g = held(id)) fence = Fence{sessionDir(id), id, owner_, *g};
  return std::make_unique<FileLog>(journal, syncInterval_, std::move(fence));
}

bool SessionStore::exists(const std::string& id) const {
  std::error_code ec;
  return fs::exists(sessionDir(id) / "session.json", ec);
}

std::optional<SessionSecrets> SessionStore::secrets(const std::string& id) const {
  if (!exists(id)) return std::nullopt;
  std::ifstream in(sessionDir(id) / "session.json");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const json j = json::parse(text, nullptr, false);
  if (!j.is_object() || !j.contains("token") || !j.contains("view_token") || !j["token"].is_string() ||
      !j["view_token"].is_string())
    throw std::runtime_error("unreadable " + (sessionDir(id) / "session.json").string());
  return SessionSecrets{j["token"].get<std::string>(), j["view_token"].get<std::string>()};
}

std::unique_ptr<SessionLog> SessionStore::create(const std::string& id, const SessionSecrets& secrets,
                                                 const Volume& volume) {
  const fs::path dir = sessionDir(id);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
  ::chmod(dir.c_str(), 0700);
  auto journal = snapshot(id, volume);
  // session.json last: a session exists at rest only once it can be recovered.
  const std::string meta = json{{"token", secrets.token}, {"view_token", secrets.viewToken}}.dump();
  writeFileAtomically(dir / "session.json", meta.data(), meta.size());
  syncDirectory(dir);
  return journal;
}

std::unique_ptr<SessionLog> SessionStore::snapshot(const std::string& id, const Volume& volume,
                                                   const std::vector<json>& head) {
  const fs::path dir = sessionDir(id);
  std::unique_ptr<LeaseLock> fenced;
  if (const auto g = held(id)) fenced = Fence{dir, id, owner_, *g}.hold();
  const std::uint64_t r = volume.revision();
  // The journal first, whole: a journal-R without snapshot-R continues the old journal's
  // revision R at recovery (its head re-announces strokes, which replay accepts), while a
  // snapshot-R without its journal's head would leave the open strokes' next dabs unreplayable.
  std::string text;
  for (const json& rec : head) text += journalLine(rec);
  writeFileAtomically(journalPath(dir, r), text.data(), text.size());
  const std::vector<std::uint8_t> bytes = saveVolume(volume);
  writeFileAtomically(snapshotPath(dir, r), bytes.data(), bytes.size());
  auto journal = openLog(id, journalPath(dir, r));
  // Keep this snapshot and the one before it, with every journal and upload from that one on.
  const std::vector<std::uint64_t> snaps = revisions(dir, "snapshot-", ".mzv");
  std::uint64_t keepFrom = r;
  for (const std::uint64_t s : snaps)
    if (s < r) keepFrom = s;
  std::error_code ec;
  for (const std::uint64_t s : snaps)
    if (s < keepFrom) fs::remove(snapshotPath(dir, s), ec);
  for (const std::uint64_t j : revisions(dir, "journal-", ".log"))
    if (j < keepFrom) fs::remove(journalPath(dir, j), ec);
  for (const std::uint64_t l : revisions(dir, "load-", ".mzv"))
    if (l <= keepFrom) fs::remove(dir / ("load-" + std::to_string(l) + ".mzv"), ec);
  for (const std::uint64_t l : revisions(dir, "step-", ".bin"))
    if (l <= keepFrom) fs::remove(dir / ("step-" + std::to_string(l) + ".bin"), ec);
  return journal;
}

std::string SessionStore::saveStep(const std::string& id, std::uint64_t revision,
                                   const std::vector<std::pair<Int3, BrickRef>>& bricks) {
  const std::vector<std::uint8_t> b = encodeStep(bricks);
  const std::string name = "step-" + std::to_string(revision) + ".bin";
  checkFence(id);
  writeFileAtomically(sessionDir(id) / name, b.data(), b.size());
  return name;
}

std::string SessionStore::saveUpload(const std::string& id, std::uint64_t revision,
                                     std::span<const std::uint8_t> file) {
  const std::string name = "load-" + std::to_string(revision) + ".mzv";
  checkFence(id);
  writeFileAtomically(sessionDir(id) / name, file.data(), file.size());
  return name;
}

Recovered SessionStore::recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) {
  const fs::path dir = sessionDir(id);
  std::vector<std::uint64_t> snaps = revisions(dir, "snapshot-", ".mzv");
  std::optional<Volume> base;
  std::uint64_t baseRevision = 0;
  for (auto it = snaps.rbegin(); it != snaps.rend() && !base; ++it) {
    try {
      base = loadVolumeFile(snapshotPath(dir, *it).string());
      baseRevision = *it;
    } catch (const std::exception& e) {
      warn("session " + id + ": snapshot " + snapshotPath(dir, *it).string() + " is unreadable (" + e.what() +
           "); falling back to the one before");
    }
  }
  if (!base) throw std::runtime_error("session " + id + ": no readable snapshot in " + dir.string());
  Recovered out;
  out.session = std::make_unique<Session>(std::move(*base), historyBytes);
  Replay replay(*out.session, [&dir](const std::string& name) { return readFile(dir / name); }, pool);
  std::vector<std::uint64_t> journals;
  for (const std::uint64_t j : revisions(dir, "journal-", ".log"))
    if (j >= baseRevision) journals.push_back(j);
  for (std::size_t k = 0; k < journals.size(); ++k) {
    if (out.session->revision() != journals[k]) {
      warn("session " + id + ": journal-" + std::to_string(journals[k]) + " does not continue revision " +
           std::to_string(out.session->revision()) + "; stopping there");
      journals.resize(k);
      break;
    }
    const bool last = k + 1 == journals.size();
    for (const json& rec : Journal::read(journalPath(dir, journals[k]), last, log_)) {
      replay.apply(rec);
      ++out.replayed;
    }
  }
  replay.finish();
  const std::uint64_t appendTo = journals.empty() ? baseRevision : journals.back();
  out.journal = openLog(id, journalPath(dir, appendTo));
  return out;
}

std::optional<std::uint64_t> SessionStore::takeLease(const std::string& id, const std::string& owner,
                                                    std::chrono::milliseconds ttl,
                                                    std::optional<std::uint64_t> heldGeneration) const {
  const fs::path dir = sessionDir(id);
  std::error_code ec;
  fs::create_directories(dir, ec);
  ::chmod(dir.c_str(), 0700);
  const LeaseLock lock(dir, true);
  const Lease current = readLease(dir / "lease");
  const long long now = nowMs();
  std::uint64_t generation = 0;
  if (heldGeneration) {
    // Renewal: only of the very lease held, expired or not; if anyone took it since, it is lost.
    if (current.owner != owner || current.generation != *heldGeneration) return std::nullopt;
    generation = *heldGeneration;
  } else {
    if (!current.owner.empty() && current.owner != owner && current.expiresMs > now) return std::nullopt;
    generation = std::max(current.generation, lock.lastGeneration()) + 1;
    lock.setLastGeneration(generation);
  }
  const std::string text = owner + " " + std::to_string(now + ttl.count()) + " " + std::to_string(generation) + "\n";
  writeFileAtomically(dir / "lease", text.data(), text.size());
  return generation;
}

void SessionStore::releaseLease(const std::string& id, const std::string& owner,
                                std::optional<std::uint64_t> heldGeneration) const {
  const fs::path dir = sessionDir(id);
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  const LeaseLock lock(dir, true);
  const Lease current = readLease(dir / "lease");
  if (current.owner == owner && (!heldGeneration || current.generation == *heldGeneration)) fs::remove(dir / "lease", ec);
}

bool SessionStore::acquire(const std::string& id) {
  const auto g = takeLease(id, owner_, ttl_);
  if (!g) return false;
  const std::lock_guard lock(mutex_);
  leases_[id] = *g;
  return true;
}

bool SessionStore::renew(const std::string& id) {
  const auto g = held(id);
  if (!g) return false;
  // A lost lease stays recorded until release(): the session's writes keep being refused.
  return takeLease(id, owner_, ttl_, g).has_value();
}

bool SessionStore::holds(const std::string& id) {
  try {
    checkFence(id);
    return held(id).has_value();
  } catch (const std::exception&) {
    return false;
  }
}

void SessionStore::release(const std::string& id) {
  std::optional<std::uint64_t> g;
  {
    const std::lock_guard lock(mutex_);
    const auto it = leases_.find(id);
    if (it == leases_.end()) return;
    g = it->second;
    leases_.erase(it);
  }
  releaseLease(id, owner_, g);
}

void SessionStore::remove(const std::string& id) {
  checkFence(id);
  {
    const std::lock_guard lock(mutex_);
    leases_.erase(id);
  }
  removeSessionFolder(sessionDir(id));
}

std::vector<std::string> SessionStore::removeUntouched(std::chrono::seconds maxAge,
                                                       const std::function<bool(const std::string&)>& live) {
  std::vector<std::string> removed;
  for (const std::string& id : sessionsUntouchedFor(dir_ / "sessions", maxAge, live)) {
    if (!takeLease(id, owner_, ttl_)) continue;
    std::error_code ec;
    fs::remove_all(sessionDir(id), ec);
    if (ec) warn("session " + id + ": removing it after " + std::to_string(maxAge.count() / 86400) + " days failed: " + ec.message());
    else removed.push_back(id);
  }
  return removed;
}

}  // namespace marzipan::service
