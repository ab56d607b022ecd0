// The hub's durability paths through its storage interface (service/session_storage.hpp), in
// milliseconds: a FaultyStorage wraps the real file store (in a scratch directory) and fails
// what a test tells it to (an append, with an I/O error or as fenced; a lease lost as a watch
// would report it), so the hub's rollback, closing and shutdown saving run without processes.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <mutex>

#include <nlohmann/json.hpp>

#include "engine/measures.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume_file.hpp"
#include "service/hub.hpp"
#include "service/session_store.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;

namespace {

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("marzipan-storage-" + name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

// The file store with faults on demand. Counters and switches are atomics: the hub calls from
// its workers while the test thread sets them.
class FaultyStorage final : public SessionStorage {
 public:
  explicit FaultyStorage(const std::filesystem::path& dir) : inner_(dir, {}, {}, "faulty-test") {}

  std::atomic<int> failAppends{0};   // the next N appends throw an I/O error
  std::atomic<bool> lapsed{false};   // holds() answers false, as after a pause past the lease
  std::atomic<int> fenceAppends{0};  // the next N appends throw OwnershipLost
  std::atomic<int> appends{0}, snapshots{0};

  // What a backend that watches its leases does when one is lost.
  void loseLease(const std::string& id) {
    std::function<void(const std::string&)> handler;
    {
      const std::lock_guard lock(mutex_);
      handler = lost_;
    }
    REQUIRE(handler);
    handler(id);
  }
  SessionStore& inner() { return inner_; }

  bool persistent() const override { return true; }
  std::string where() const override { return "faulty " + inner_.where(); }
  bool acquire(const std::string& id) override { return inner_.acquire(id); }
  bool renew(const std::string& id) override { return inner_.renew(id); }
  bool holds(const std::string& id) override { return !lapsed && inner_.holds(id); }
  void release(const std::string& id) override { inner_.release(id); }
  std::chrono::milliseconds renewEvery() const override { return inner_.renewEvery(); }
  void onLost(std::function<void(const std::string&)> handler) override {
    const std::lock_guard lock(mutex_);
    lost_ = std::move(handler);
  }
  bool exists(const std::string& id) const override { return inner_.exists(id); }
  std::optional<SessionSecrets> secrets(const std::string& id) const override { return inner_.secrets(id); }
  std::unique_ptr<SessionLog> create(const std::string& id, const SessionSecrets& s, const Volume& v) override {
    return wrap(inner_.create(id, s, v));
  }
  std::unique_ptr<SessionLog> snapshot(const std::string& id, const Volume& v, const std::vector<json>& head) override {
    ++snapshots;
    return wrap(inner_.snapshot(id, v, head));
  }
  std::string saveStep(const std::string& id, std::uint64_t r, const std::vector<std::pair<Int3, BrickRef>>& b) override {
    return inner_.saveStep(id, r, b);
  }
  std::string saveUpload(const std::string& id, std::uint64_t r, std::span<const std::uint8_t> f) override {
    return inner_.saveUpload(id, r, f);
  }
  Recovered recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) override {
    Recovered r = inner_.recover(id, historyBytes, pool);
    r.journal = wrap(std::move(r.journal));
    return r;
  }
  void remove(const std::string& id) override { inner_.remove(id); }
  std::vector<std::string> removeUntouched(std::chrono::seconds age, const std::function<bool(const std::string&)>& live) override {
    return inner_.removeUntouched(age, live);
  }

 private:
  class Log final : public SessionLog {
   public:
    Log(FaultyStorage& owner, std::unique_ptr<SessionLog> inner) : owner_(owner), inner_(std::move(inner)) {}
    void append(const json& record) override {
      if (owner_.failAppends > 0 && owner_.failAppends-- > 0) throw std::runtime_error("cannot write journal: No space left on device");
      if (owner_.fenceAppends > 0 && owner_.fenceAppends-- > 0) throw OwnershipLost("another server holds the lease now");
      inner_->append(record);
      ++owner_.appends;
    }
    void sync() override { inner_->sync(); }
    bool dirty() const override { return inner_->dirty(); }
    std::size_t records() const override { return inner_->records(); }

   private:
    FaultyStorage& owner_;
    std::unique_ptr<SessionLog> inner_;
  };
  std::unique_ptr<SessionLog> wrap(std::unique_ptr<SessionLog> log) {
    return log ? std::make_unique<Log>(*this, std::move(log)) : nullptr;
  }

  SessionStore inner_;
  std::mutex mutex_;
  std::function<void(const std::string&)> lost_;
};

HubOptions storageOptions(std::shared_ptr<SessionStorage> storage) {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  o.storage = std::move(storage);
  return o;
}

const json kCreate = {{"size", {48, 48, 48}}, {"solid", "sphere"}, {"view", "none"}};
json blob(double x) { return {{"tool", "add_blob"}, {"center", {x, 40, 24}}, {"radius", 4}}; }

int closeCodeOf(CaptureLink& link) {
  std::unique_lock lock(link.mutex);
  link.cv.wait_for(lock, kWait, [&] { return link.closeCode != 0; });
  return link.closeCode;
}

// Two clients of one session on a FaultyStorage in its own scratch directory, after one
// journaled edit; shut down and removed at the end.
struct SharedSession {
  explicit SharedSession(const std::string& name)
      : dir(scratch(name)), storage(std::make_shared<FaultyStorage>(dir)), hub(storageOptions(storage)), a(hub), b(hub) {
    created = a.result("session.create", kCreate);
    b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
    a.result("tool.apply", blob(20));
  }
  ~SharedSession() {
    hub.shutdown();
    std::filesystem::remove_all(dir);
  }
  // Both clients were closed with 1011 and the hub holds no session.
  void checkClosed() {
    CHECK(closeCodeOf(*a.link) == 1011);
    CHECK(closeCodeOf(*b.link) == 1011);
    CHECK(hub.sessionCount() == 0);
  }

  std::filesystem::path dir;
  std::shared_ptr<FaultyStorage> storage;
  Hub hub;
  TestClient a, b;
  json created;
};

}  // namespace

TEST_CASE("a failed journal append rolls the session back: revision, digest and undo as before, the client told",
          "[hub][storage]") {
  const auto dir = scratch("rollback");
  auto storage = std::make_shared<FaultyStorage>(dir);
  Hub hub(storageOptions(storage));
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
  const std::string digest0 = created["digest"];
  const json first = a.result("tool.apply", blob(20));
  const json before = a.result("session.stats");
  REQUIRE(before["revision"] == 1);

  storage->failAppends = 1;
  const std::size_t bMark = b.link->size();
  const json refused = a.call("tool.apply", blob(28));
  INFO(refused.dump());
  REQUIRE(refused.contains("error"));
  CHECK(refused["error"]["code"] == -32000);
  CHECK(refused["error"]["message"].get<std::string>().find("No space left on device") != std::string::npos);

  const json after = a.result("session.stats");
  CHECK(after["revision"] == before["revision"]);
  CHECK(after["digest"] == before["digest"]);
  CHECK(after["can_undo"] == true);
  CHECK(after["can_redo"] == false);
  // The other client heard of no change.
  for (std::size_t i = bMark; i < b.link->size(); ++i) CHECK_FALSE(isNotification(b.link->at(i), "session.changed"));
  // Undo still steps back over the first edit, to the created sphere's digest.
  const json undone = a.result("history.undo");
  CHECK(undone["revision"] == 2);
  CHECK(a.result("session.stats")["digest"] == digest0);
  // And the session goes on being journaled.
  CHECK(a.result("tool.apply", blob(28))["revision"] == 3);
  hub.shutdown();
  std::filesystem::remove_all(dir);
}

TEST_CASE("a fenced append refuses the edit and closes the session, its clients are told to join again",
          "[hub][storage]") {
  SharedSession s("fenced");
  s.storage->fenceAppends = 1;
  const int appendsBefore = s.storage->appends;
  CHECK(s.a.error("tool.apply", blob(28)) == -32015);
  CHECK(s.storage->appends == appendsBefore);  // nothing of the refused edit was written
  s.checkClosed();
}

TEST_CASE("a lease the storage reports lost closes the session and its clients", "[hub][storage]") {
  SharedSession s("lost");
  s.storage->loseLease(s.created["session"]);
  s.checkClosed();
  // The closed session answers no more edits (the connection is closed by the network layer;
  // here the hub itself refuses).
  CHECK(s.a.error("tool.apply", blob(28)) == -32009);
}

TEST_CASE("an edit that changed nothing is not acknowledged once the lease has lapsed: the session closes",
          "[hub][storage]") {
  // A server paused past its lease (SIGSTOP) may take an edit on an old connection before its
  // renewal timer runs. An edit that changes something is refused by its write's fence; one
  // that changes nothing writes nothing, so the lease itself is asked before "done" is said.
  SharedSession s("lapsed");
  const json inside = {{"tool", "add_blob"}, {"center", {24, 24, 24}}, {"radius", 3}};
  // While the lease holds, the same edit is answered: the revision stays, nothing changed.
  const json answered = s.a.result("tool.apply", inside);
  CHECK(answered["revision"] == 1);
  CHECK(answered["roi"].is_null());

  s.storage->lapsed = true;
  const int appendsBefore = s.storage->appends;
  CHECK(s.a.error("tool.apply", inside) == -32015);
  CHECK(s.storage->appends == appendsBefore);
  s.checkClosed();
}

TEST_CASE("shutdown snapshots every session at its last revision and releases its lease", "[hub][storage]") {
  const auto dir = scratch("shutdown");
  auto storage = std::make_shared<FaultyStorage>(dir);
  std::vector<std::pair<std::string, std::string>> sessions;  // id, digest
  {
    Hub hub(storageOptions(storage));
    std::vector<std::unique_ptr<TestClient>> clients;
    for (int k = 0; k < 3; ++k) {
      clients.push_back(std::make_unique<TestClient>(hub));
      const json created = clients.back()->result("session.create", kCreate);
      for (int e = 0; e <= k; ++e) clients.back()->result("tool.apply", blob(16 + 6 * e));
      sessions.emplace_back(created["session"], clients.back()->result("session.stats")["digest"]);
    }
    const int snapshotsBefore = storage->snapshots;
    hub.shutdown();
    CHECK(storage->snapshots - snapshotsBefore == 3);
  }
  for (std::size_t k = 0; k < sessions.size(); ++k) {
    const auto& [id, digest] = sessions[k];
    const auto sessionDir = dir / "sessions" / id;
    CHECK(std::filesystem::exists(sessionDir / ("snapshot-" + std::to_string(k + 1) + ".mzv")));
    CHECK_FALSE(std::filesystem::exists(sessionDir / "lease"));
    // Another server takes it at once (no lease to wait for) and finds the last revision.
    SessionStore other(dir, {}, {}, "another-server");
    REQUIRE(other.acquire(id));
    const Recovered r = other.recover(id, std::size_t(64) << 20, ThreadPool::serial());
    CHECK(r.replayed == 0);  // all in the snapshot
    CHECK(r.session->revision() == k + 1);
    CHECK(digestText(r.session->digest()) == digest);
  }
  std::filesystem::remove_all(dir);
}
