// SessionStore (see session_store.hpp), with the replay of journal records into a Session.
#include "service/session_store.hpp"

#include <fcntl.h>
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

namespace fs = std::filesystem;
using nlohmann::json;

namespace marzipan::service {

namespace {
void syncDirectory(const fs::path& dir);
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

void syncDirectory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

std::vector<std::pair<Int3, BrickRef>> readStep(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto fail = [&]() -> std::runtime_error { return std::runtime_error("unreadable step file " + path.string()); };
  if (b.size() < 12 || std::memcmp(b.data(), "MZBK", 4) != 0) throw fail();
  if (crc32Ieee({b.data(), b.size() - 4}) != le::get32(b.data() + b.size() - 4)) throw fail();
  const std::uint32_t count = le::get32(b.data() + 4);
  std::vector<std::pair<Int3, BrickRef>> out;
  std::size_t at = 8;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (at + 13 > b.size() - 4) throw fail();
    const Int3 brick{std::int32_t(le::get32(b.data() + at)), std::int32_t(le::get32(b.data() + at + 4)),
                     std::int32_t(le::get32(b.data() + at + 8))};
    const std::uint8_t kind = b[at + 12];
    at += 13;
    BrickRef ref;
    if (kind == 2) {
      if (at + sizeof(Brick) > b.size() - 4) throw fail();
      auto data = std::make_shared<Brick>();
      for (int v = 0; v < kBrickVoxels; ++v) data->v[v] = le::getF32(b.data() + at + 4 * std::size_t(v));
      at += sizeof(Brick);
      ref.data = std::move(data);
    } else {
      ref.inside = kind == 1;
    }
    out.emplace_back(brick, std::move(ref));
  }
  return out;
}

void replayRecord(Session& s, const json& rec, std::map<std::uint64_t, StrokeId>& strokes, const fs::path& dir,
                  ThreadPool& pool) {
  if (rec.contains("op")) {
    s.apply(protocol::parseOp(rec["op"]), pool);
  } else if (rec.contains("stroke_begin")) {
    // A stroke announced again at the head of a journal after a snapshot replaces its entry.
    if (const auto it = strokes.find(rec["stroke_begin"].get<std::uint64_t>()); it != strokes.end()) {
      s.endStroke(it->second);
      strokes.erase(it);
    }
    const auto tool = fromWireName(protocol::kBrushToolNames, rec.at("tool").get<std::string>());
    if (!tool) throw std::runtime_error("unknown stroke tool");
    const std::string sym = rec.value("symmetry", "");
    const Symmetry symmetry{sym.find('x') != std::string::npos, sym.find('y') != std::string::npos,
                            sym.find('z') != std::string::npos};
    const StrokeId id = s.beginStroke(*tool, rec.at("radius").get<double>(), rec.at("strength").get<double>(), symmetry,
                                      rec.value("accumulate", false));
    strokes[rec["stroke_begin"].get<std::uint64_t>()] = id;
    if (const auto it = rec.find("applied"); it != rec.end()) {
      // What the stroke had applied before the snapshot: its next dabs add only the excess.
      std::vector<StrokeDab> applied;
      for (const json& d : *it) {
        const StrokeDab dab{Vec3{d.at(0).get<double>(), d.at(1).get<double>(), d.at(2).get<double>()}, d.at(3).get<double>()};
        if (!isFinite(dab.center) || !(dab.weight > 0 && dab.weight <= 1)) throw std::runtime_error("bad stroke memory");
        applied.push_back(dab);
      }
      s.setStrokeMemory(id, std::move(applied));
    }
  } else if (rec.contains("stroke_end")) {
    const auto it = strokes.find(rec["stroke_end"].get<std::uint64_t>());
    if (it != strokes.end()) {
      s.endStroke(it->second);
      strokes.erase(it);
    }
  } else if (rec.contains("stroke")) {
    std::vector<Dab> dabs;
    for (const json& d : rec.at("dabs")) dabs.push_back(Dab{Vec3{d[0], d[1], d[2]}, d[3].get<double>()});
    s.strokeDabs(strokes.at(rec["stroke"].get<std::uint64_t>()), dabs, pool);
  } else if (rec.contains("undo") || rec.contains("redo")) {
    // From the bricks it put in place, not from the replayed history: that history starts at
    // the snapshot and may hold only part of a stroke that began before it.
    const bool undo = rec.contains("undo");
    s.restore(readStep(dir / rec[undo ? "undo" : "redo"].get<std::string>()));
  } else if (rec.contains("load")) {
    s.load(loadVolumeFile((dir / rec["load"].get<std::string>()).string()));
  } else {
    throw std::runtime_error("unknown journal record");
  }
}

}  // namespace

SessionStore::SessionStore(fs::path dataDir, std::chrono::milliseconds syncInterval,
                           std::function<void(const std::string&)> log)
    : dir_(std::move(dataDir)), syncInterval_(syncInterval), log_(std::move(log)) {
  if (dir_.empty()) return;
  std::error_code ec;
  fs::create_directories(dir_ / "sessions", ec);
  if (ec) throw std::runtime_error("cannot create " + (dir_ / "sessions").string() + ": " + ec.message());
  ::chmod((dir_ / "sessions").c_str(), 0700);
}

fs::path SessionStore::sessionDir(const std::string& id) const { return dir_ / "sessions" / id; }

bool SessionStore::exists(const std::string& id) const {
  if (!enabled()) return false;
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

std::unique_ptr<Journal> SessionStore::create(const std::string& id, const SessionSecrets& secrets,
                                              const Volume& volume) const {
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

std::unique_ptr<Journal> SessionStore::snapshot(const std::string& id, const Volume& volume,
                                                const std::vector<json>& head) const {
  const fs::path dir = sessionDir(id);
  const std::uint64_t r = volume.revision();
  // The journal first, whole: a journal-R without snapshot-R continues the old journal's
  // revision R at recovery (its head re-announces strokes, which replay accepts), while a
  // snapshot-R without its journal's head would leave the open strokes' next dabs unreplayable.
  std::string text;
  for (const json& rec : head) text += journalLine(rec);
  writeFileAtomically(journalPath(dir, r), text.data(), text.size());
  const std::vector<std::uint8_t> bytes = saveVolume(volume);
  writeFileAtomically(snapshotPath(dir, r), bytes.data(), bytes.size());
  auto journal = std::make_unique<Journal>(journalPath(dir, r), syncInterval_);
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
                                   const std::vector<std::pair<Int3, BrickRef>>& bricks) const {
  std::vector<std::uint8_t> b{'M', 'Z', 'B', 'K'};
  const auto put = [&b](std::uint32_t v) {
    const std::size_t at = b.size();
    b.resize(at + 4);
    le::put32(b.data() + at, v);
  };
  put(std::uint32_t(bricks.size()));
  for (const auto& [brick, ref] : bricks) {
    put(std::uint32_t(brick.x));
    put(std::uint32_t(brick.y));
    put(std::uint32_t(brick.z));
    b.push_back(ref.data ? 2 : ref.inside ? 1 : 0);
    if (ref.data)
      for (const float v : ref.data->v) put(std::bit_cast<std::uint32_t>(v));
  }
  put(crc32Ieee(b));
  const std::string name = "step-" + std::to_string(revision) + ".bin";
  writeFileAtomically(sessionDir(id) / name, b.data(), b.size());
  return name;
}

std::string SessionStore::saveUpload(const std::string& id, std::uint64_t revision,
                                     std::span<const std::uint8_t> file) const {
  const std::string name = "load-" + std::to_string(revision) + ".mzv";
  writeFileAtomically(sessionDir(id) / name, file.data(), file.size());
  return name;
}

Recovered SessionStore::recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) const {
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
  std::map<std::uint64_t, StrokeId> strokes;
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
      replayRecord(*out.session, rec, strokes, dir, pool);
      ++out.replayed;
      if (rec.contains("r") && rec["r"].get<std::uint64_t>() != out.session->revision())
        throw std::runtime_error("session " + id + ": replay reached revision " + std::to_string(out.session->revision()) +
                                 " where the journal says " + rec["r"].dump());
    }
  }
  for (const auto& [journalStroke, stroke] : strokes) out.session->endStroke(stroke);
  const std::uint64_t appendTo = journals.empty() ? baseRevision : journals.back();
  out.journal = std::make_unique<Journal>(journalPath(dir, appendTo), syncInterval_);
  return out;
}

bool SessionStore::takeLease(const std::string& id, const std::string& owner, std::chrono::milliseconds ttl) const {
  if (!enabled()) return true;
  const fs::path dir = sessionDir(id);
  const fs::path lease = dir / "lease";
  const auto nowMs = std::chrono::duration_cast<std::chrono::milliseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  const auto read = [](const fs::path& p) -> std::pair<std::string, long long> {
    std::ifstream in(p);
    std::string who;
    long long expires = 0;
    if (!(in >> who >> expires)) return {"", 0};
    return {who, expires};
  };
  std::error_code ec;
  fs::create_directories(dir, ec);
  ::chmod(dir.c_str(), 0700);
  const std::string text = owner + " " + std::to_string(nowMs + ttl.count()) + "\n";
  const auto [who, expires] = read(lease);
  if (who == owner) {
    // Only the holder rewrites a live lease, so replacing it is safe.
    writeFileAtomically(lease, text.data(), text.size());
    return read(lease).first == owner;
  }
  if (!who.empty() && expires > nowMs) return false;
  if (!who.empty()) {
    // An expired lease: move it aside first. Of several servers doing so at once only one
    // rename finds it; the others then lose the race to create the new one below.
    const fs::path stale = dir / ("lease.stale." + owner);
    if (::rename(lease.c_str(), stale.c_str()) != 0) return false;
    const auto [staleWho, staleExpires] = read(stale);
    fs::remove(stale, ec);
    if (staleWho != who || staleExpires != expires) return false;  // it was renewed meanwhile
  }
  // Create it exclusively: link() fails when another server made one first.
  const fs::path mine = dir / ("lease.new." + owner);
  writeFileAtomically(mine, text.data(), text.size());
  const bool won = ::link(mine.c_str(), lease.c_str()) == 0;
  fs::remove(mine, ec);
  return won;
}

void SessionStore::releaseLease(const std::string& id, const std::string& owner) const {
  if (!enabled()) return;
  const fs::path lease = sessionDir(id) / "lease";
  std::ifstream in(lease);
  std::string who;
  if (in >> who && who == owner) {
    std::error_code ec;
    fs::remove(lease, ec);
  }
}

std::vector<std::string> SessionStore::removeUntouched(std::chrono::seconds maxAge, const std::string& owner,
                                                       std::chrono::milliseconds ttl,
                                                       const std::function<bool(const std::string&)>& live) const {
  std::vector<std::string> removed;
  if (!enabled()) return removed;
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (const fs::directory_entry& entry : fs::directory_iterator(dir_ / "sessions", ec)) {
    const std::string id = entry.path().filename().string();
    if (!entry.is_directory(ec) || live(id)) continue;
    bool old = true;
    for (const fs::directory_entry& file : fs::directory_iterator(entry.path(), ec))
      if (now - file.last_write_time(ec) < maxAge) old = false;
    if (!old || !takeLease(id, owner, ttl)) continue;
    fs::remove_all(entry.path(), ec);
    if (ec) warn("session " + id + ": removing it after " + std::to_string(maxAge.count() / 86400) + " days failed: " + ec.message());
    else removed.push_back(id);
  }
  return removed;
}

json strokeBeginRecord(StrokeId id, const Session::StrokeParams& st) {
  const std::string symmetry =
      std::string(st.symmetry.x ? "x" : "") + (st.symmetry.y ? "y" : "") + (st.symmetry.z ? "z" : "");
  json record{{"stroke_begin", id},
              {"tool", protocol::nameOf(protocol::kBrushToolNames, st.tool)},
              {"radius", st.radius},
              {"strength", st.strength},
              {"symmetry", symmetry}};
  if (st.accumulate) record["accumulate"] = true;
  if (!st.memory.empty()) {
    json applied = json::array();
    for (const StrokeDab& d : st.memory) applied.push_back({d.center.x, d.center.y, d.center.z, d.weight});
    record["applied"] = std::move(applied);
  }
  return record;
}

}  // namespace marzipan::service
