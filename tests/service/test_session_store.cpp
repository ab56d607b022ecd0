// Sessions at rest: after every acknowledged change the data directory alone recovers the exact
// digest (the directory is copied at that moment, as a crash would leave it); a corrupt newest
// snapshot falls back to the one before; leases keep a session on one server.
#include <catch2/catch.hpp>

#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <variant>

#include <nlohmann/json.hpp>

#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "service/hub.hpp"
#include "service/session_store.hpp"
#include "storage_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::freshDir;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// Responses by id, nothing else.
struct Responses : ClientLink {
  std::mutex mutex;
  std::condition_variable cv;
  std::map<int, json> byId;
  void sendText(std::string text) override {
    const json j = json::parse(text);
    if (!j.contains("id") || !j["id"].is_number_integer()) return;
    const std::lock_guard lock(mutex);
    byId[j["id"].get<int>()] = j;
    cv.notify_all();
  }
  void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>>, bool) override {}
  void close(int, std::string) override {}
};

struct Driver {
  Hub& hub;
  std::shared_ptr<Responses> link = std::make_shared<Responses>();
  std::shared_ptr<HubClient> client = hub.connect(link, "test");
  int id = 1;
  explicit Driver(Hub& h) : hub(h) {}
  ~Driver() { hub.disconnect(client); }
  json call(const std::string& method, const json& params = json::object()) {
    const int my = id++;
    hub.text(client, json{{"jsonrpc", "2.0"}, {"id", my}, {"method", method}, {"params", params}}.dump());
    std::unique_lock lock(link->mutex);
    REQUIRE(link->cv.wait_for(lock, std::chrono::seconds(20), [&] { return link->byId.count(my) > 0; }));
    const json r = link->byId[my];
    INFO(r.dump());
    REQUIRE(r.contains("result"));
    return r["result"];
  }
};

std::string recoveredDigest(const fs::path& dataDir, const std::string& id, std::uint64_t* revision = nullptr) {
  SessionStore store(dataDir);
  const Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  if (revision) *revision = r.session->revision();
  return digestHex(r.session->volume());
}

}  // namespace

TEST_CASE("every acknowledged change is recoverable from the data directory alone", "[store]") {
  const fs::path dir = freshDir("every"), copy = freshDir("every-copy");
  HubOptions o;
  o.workers = 2;
  o.dataDir = dir;
  o.snapshotEvery = 5;  // several snapshots and journals along the way
  Hub hub(o);
  Driver a(hub);
  const json created = a.call("session.create", {{"size", {48, 48, 48}}, {"solid", "sphere"}, {"view", "none"}});
  const std::string id = created["session"];
  const json steps[] = {
      {"tool.apply", {{"tool", "add_blob"}, {"center", {24, 41, 24}}, {"radius", 5}}},
      {"stroke.begin", {{"tool", "remove_blob"}, {"radius", 4}, {"symmetry", {"x"}}}},
      {"stroke.dabs", {{"stroke", 1}, {"dabs", {{{"center", {14, 30, 24}}}, {{"ray", {{"origin", {23.5, 23.5, 100}}, {"direction", {0, 0, -1}}}}, {"pressure", 0.5}}}}}},
      {"stroke.dabs", {{"stroke", 1}, {"dabs", {{{"center", {16, 34, 24}}}}}}},
      {"stroke.end", {{"stroke", 1}}},
      {"history.undo", json::object()},
      {"history.redo", json::object()},
      {"volume.morph", {{"kind", "dilate"}, {"radius", 1}}},
      {"history.undo", json::object()},
      {"tool.apply", {{"tool", "csg_subtract"}, {"shape", "box"}, {"center", {24, 24, 40}}, {"radius", 6}}},
      {"tool.apply", {{"tool", "smooth"}, {"global", true}, {"iterations", 2}}},
  };
  for (const json& step : steps) {
    a.call(step[0], step[1]);
    const json stats = a.call("session.stats");
    fs::remove_all(copy);
    fs::copy(dir, copy, fs::copy_options::recursive);
    std::uint64_t revision = 0;
    INFO(step.dump());
    CHECK(recoveredDigest(copy, id, &revision) == stats["digest"].get<std::string>());
    CHECK(revision == stats["revision"].get<std::uint64_t>());
  }
  fs::remove_all(dir);
  fs::remove_all(copy);
}

TEST_CASE("a stroke cut by snapshots recovers its memory: the same digest after every message", "[store]") {
  // A snapshot after every 3 journal records (the re-announced stroke and two messages), so that the stroke's messages fall on both sides
  // of them; its overlapping dabs only add what exceeds the earlier ones, so a replay that
  // forgot them would build up and read another digest. A stroke with a height anchors its dabs
  // on normals of the volume as the stroke began, which a replay after a snapshot no longer has:
  // they come from the journal.
  const fs::path dir = freshDir("stroke"), copy = freshDir("stroke-copy");
  HubOptions o;
  o.workers = 2;
  o.dataDir = dir;
  o.snapshotEvery = 3;
  Hub hub(o);
  Driver a(hub);
  const json created = a.call("session.create", {{"size", {48, 48, 48}}, {"solid", "sphere"}, {"view", "none"}});
  const std::string id = created["session"];
  for (const json& kind : {json{{"accumulate", false}}, json{{"accumulate", true}}, json{{"height", 2.5}}}) {
    json params{{"tool", "add_blob"}, {"radius", 5}, {"symmetry", {"x"}}};
    params.update(kind);
    const json begun = a.call("stroke.begin", params);
    const std::uint64_t stroke = begun["stroke"];
    for (int m = 0; m < 6; ++m) {
      const double x = 18 + m;
      a.call("stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", {x, 40.5, 24}}}, {{"center", {x + 0.5, 40.5, 24}}, {"pressure", 0.7}}}}});
      const json stats = a.call("session.stats");
      fs::remove_all(copy);
      fs::copy(dir, copy, fs::copy_options::recursive);
      INFO(kind.dump() << ", message " << m);
      CHECK(recoveredDigest(copy, id) == stats["digest"].get<std::string>());
    }
    a.call("stroke.end", {{"stroke", stroke}});
  }
  fs::remove_all(dir);
  fs::remove_all(copy);
}

TEST_CASE("a corrupt newest snapshot falls back to the previous one and both journals", "[store]") {
  const fs::path dir = freshDir("corrupt");
  HubOptions o;
  o.workers = 2;
  o.dataDir = dir;
  o.snapshotEvery = 3;
  std::string id, digest;
  {
    Hub hub(o);
    Driver a(hub);
    id = a.call("session.create", {{"size", {40, 40, 40}}, {"solid", "torus"}, {"view", "none"}})["session"];
    for (int i = 0; i < 4; ++i) a.call("tool.apply", {{"tool", "add_blob"}, {"ray", {{"origin", {19.5, 19.5 + i, 100}}, {"direction", {0, 0, -1}}}}});
    digest = a.call("session.stats")["digest"];
  }
  const fs::path sdir = dir / "sessions" / id;
  std::vector<fs::path> snaps;
  for (const auto& e : fs::directory_iterator(sdir))
    if (e.path().filename().string().rfind("snapshot-", 0) == 0) snaps.push_back(e.path());
  REQUIRE(snaps.size() == 2);
  const fs::path newest = fs::file_size(snaps[0]) && snaps[0].string() > snaps[1].string() ? snaps[0] : snaps[1];
  {
    std::fstream f(newest, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x5a');
  }
  std::vector<std::string> warnings;
  SessionStore store(dir, {}, [&](const std::string& w) { warnings.push_back(w); });
  const Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  CHECK(digestHex(r.session->volume()) == digest);
  CHECK(warnings.size() >= 1);
  fs::remove_all(dir);
}

TEST_CASE("a lease keeps a session on one server until it expires or is released", "[store]") {
  const fs::path dir = freshDir("lease");
  SessionStore store(dir);
  CHECK(store.takeLease("abc", "server-a", std::chrono::milliseconds(60'000)).has_value());
  CHECK(store.takeLease("abc", "server-a", std::chrono::milliseconds(60'000)).has_value());
  CHECK_FALSE(store.takeLease("abc", "server-b", std::chrono::milliseconds(60'000)).has_value());
  store.releaseLease("abc", "server-b");
  CHECK_FALSE(store.takeLease("abc", "server-b", std::chrono::milliseconds(60'000)).has_value());
  store.releaseLease("abc", "server-a");
  CHECK(store.takeLease("abc", "server-b", std::chrono::milliseconds(1)).has_value());
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  CHECK(store.takeLease("abc", "server-a", std::chrono::milliseconds(60'000)).has_value());
  fs::remove_all(dir);
}

TEST_CASE("leases are fenced: a holder that stalled past its expiry can neither renew over nor write after the new one",
          "[store]") {
  const fs::path dir = freshDir("fence");
  const auto ttl = std::chrono::milliseconds(30);
  SessionStore a(dir, {}, {}, "server-a", ttl), b(dir, {}, {}, "server-b", ttl);
  Session live(makeSolid(SolidKind::Sphere, {32, 32, 32}));
  REQUIRE(a.acquire("s"));
  std::unique_ptr<SessionLog> journalA = a.create("s", {"t", "v"}, live.volume());
  journalA->append({{"stroke_end", 1}});
  CHECK(a.renew("s"));
  CHECK(a.holds("s"));
  CHECK_FALSE(b.holds("s"));
  CHECK_FALSE(a.holds("another"));
  std::this_thread::sleep_for(ttl * 2);
  // Expired but not taken: a's writes would still pass, and so does the question.
  CHECK(a.holds("s"));
  // a stalled: its lease expired and b took it, with a newer generation.
  REQUIRE(b.acquire("s"));
  const auto leaseText = [&] {
    std::ifstream in(dir / "sessions" / "s" / "lease");
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string bLease = leaseText();
  CHECK(bLease.rfind("server-b ", 0) == 0);
  CHECK(bLease.substr(bLease.rfind(' ') + 1) == "2\n");
  // What an edit that writes nothing asks before it is acknowledged (hub Durability::confirmHeld).
  CHECK_FALSE(a.holds("s"));
  CHECK(b.holds("s"));
  // a's renewal finds the lease taken and leaves b's untouched; a's append is refused and
  // leaves the journal as it was.
  CHECK_FALSE(a.renew("s"));
  CHECK(leaseText() == bLease);
  const auto journalBytes = fs::file_size(dir / "sessions" / "s" / "journal-0.log");
  CHECK_THROWS_AS(journalA->append({{"stroke_end", 2}}), OwnershipLost);
  CHECK(fs::file_size(dir / "sessions" / "s" / "journal-0.log") == journalBytes);
  CHECK_THROWS_AS(a.snapshot("s", live.volume()), OwnershipLost);
  // b writes on; a release by a (which no longer holds it) leaves b's lease alone.
  const Recovered rb = b.recover("s", std::size_t(64) << 20, ThreadPool::serial());
  rb.journal->append({{"stroke_end", 3}});
  a.release("s");
  a.releaseLease("s", "server-a", 1);
  CHECK(leaseText() == bLease);
  // Generations only grow, also across a released (removed) lease.
  b.release("s");
  CHECK_FALSE(fs::exists(dir / "sessions" / "s" / "lease"));
  REQUIRE(a.acquire("s"));
  CHECK(leaseText().substr(leaseText().rfind(' ') + 1) == "3\n");
  CHECK_THROWS_AS(rb.journal->append({{"stroke_end", 4}}), OwnershipLost);
  fs::remove_all(dir);
}

TEST_CASE("a snapshot's journal starts with the open strokes, and a rotation cut short is recovered", "[store]") {
  const fs::path dir = freshDir("rotation");
  SessionStore store(dir);
  Session live(makeSolid(SolidKind::Sphere, {64, 64, 64}));
  std::unique_ptr<SessionLog> journal = store.create("rot", {"t", "v"}, live.volume());
  const StrokeId stroke = live.beginStroke(protocol::BrushTool::AddBlob, 6, 1);
  journal->append({{"stroke_begin", stroke}, {"tool", "add_blob"}, {"radius", 6}, {"strength", 1}, {"symmetry", ""}});
  const auto dab = [&](double x) {
    live.strokeDabs(stroke, {Dab{Vec3{x, 54, 32}, 1.0}}, ThreadPool::serial());
    journal->append({{"r", live.revision()}, {"stroke", stroke}, {"dabs", {{x, 54, 32, 1.0}}}});
  };
  dab(30);
  // The rotation writes the new journal with the stroke's begin record, then the snapshot.
  const json head = strokeBeginRecord(stroke, live.openStrokeList().at(0).second);
  CHECK(head.contains("applied"));  // the stroke's memory: its next dabs add only the excess
  journal = store.snapshot("rot", live.volume(), {head});
  CHECK(journal->records() == 1);
  dab(34);
  std::uint64_t revision = 0;
  CHECK(recoveredDigest(dir, "rot", &revision) == digestHex(live.volume()));
  CHECK(revision == live.revision());

  // Cut short after the journal, before the snapshot: the old journal goes on, the new one's
  // head is replayed (or skipped) without breaking recovery.
  const std::uint64_t r = live.revision();
  journal.reset();
  {
    std::ofstream partial(dir / "sessions" / "rot" / ("journal-" + std::to_string(r) + ".log"), std::ios::binary);
    partial << journalLine(head);
  }
  CHECK(recoveredDigest(dir, "rot", &revision) == digestHex(live.volume()));
  CHECK(revision == r);
  fs::remove_all(dir);
}

TEST_CASE("sessions at rest untouched longer than the age limit are removed, younger and live ones kept", "[store]") {
  const fs::path dir = freshDir("untouched");
  SessionStore store(dir);
  testing::checkRemovesUntouched(store, dir);
  fs::remove_all(dir);
}
