// Long requests on the hub: op.progress notifications, op.cancel, the per-request work budget
// (max_op_voxels), other sessions served meanwhile, shutdown with an operation running, and a
// global operation that fails part way (service/hub.hpp, engine/progress.hpp).
#include <catch2/catch.hpp>

#include <condition_variable>
#include <filesystem>
#include <future>
#include <set>
#include <thread>

#include "engine/solids.hpp"
#include "engine/volume_file.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using Clock = std::chrono::steady_clock;

namespace {

HubOptions longOptions() {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  return o;
}

const json kCreatePig = {{"size", {128, 128, 128}}, {"solid", "pig"}, {"view", "none"}};
// Hours of work on any machine unless cancelled (under the default budget on 128^3).
const json kBlob = {{"tool", "add_blob"}, {"ray", {{"origin", {64, 64, 300}}, {"direction", {0, 0, -1}}}}, {"radius", 8}};
const json kLongSmooth = {{"tool", "smooth"}, {"global", true}, {"iterations", 1500}};

json sendLong(TestClient& c, int id, const std::string& method, const json& params) {
  c.hub.text(c.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump());
  return id;
}

// Waits for the first op.progress of request `id` with a fraction above 0.
json waitProgress(TestClient& c, int id) {
  const std::size_t at = c.link->waitFor([&](const auto& m) {
    return isNotification(m, "op.progress") && std::get<json>(m)["params"]["request"] == id &&
           std::get<json>(m)["params"]["fraction"].template get<double>() > 0;
  });
  return std::get<json>(c.link->at(at))["params"];
}

json responseTo(TestClient& c, int id) {
  return std::get<json>(c.link->at(c.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
}

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("marzipan-long-ops-" + name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

}  // namespace

TEST_CASE("a long global smoothing reports progress, op.cancel stops it and changes nothing, also after a reload", "[hub][long]") {
  const auto dir = scratch("cancel");
  HubOptions o = longOptions();
  o.dataDir = dir;
  json created, before;
  {
    Hub hub(o);
    TestClient a(hub);
    created = a.result("session.create", kCreatePig);
    CHECK(created["limits"]["max_op_voxels"].get<double>() == o.limits.maxOpVoxels);
    a.result("tool.apply", kBlob);
    before = a.result("session.stats");

    sendLong(a, 50, "tool.apply", kLongSmooth);
    const json first = waitProgress(a, 50);
    CHECK(first["fraction"].get<double>() < 0.5);
    // Fractions never go down and come at most every 250 ms.
    const json cancel = a.call("op.cancel");
    REQUIRE(cancel.contains("result"));
    CHECK(cancel["result"]["cancelled"] == true);
    const json answer = responseTo(a, 50);
    INFO(answer.dump());
    REQUIRE(answer.contains("error"));
    CHECK(answer["error"]["code"] == -32016);
    const json after = a.result("session.stats");
    CHECK(after["revision"] == before["revision"]);
    CHECK(after["digest"] == before["digest"]);
    CHECK(after["can_undo"] == true);  // the blob is still the newest step
    // Nothing is running now: a second cancel finds nothing.
    CHECK(a.result("op.cancel")["cancelled"] == false);
    // The session goes on: undo takes back the blob, not a half smoothing.
    a.result("history.undo");
    before = a.result("session.stats");
  }
  {
    // Replayed from the journal: the same revision and digest.
    Hub hub(o);
    TestClient b(hub);
    b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
    const json replayed = b.result("session.stats");
    CHECK(replayed["revision"] == before["revision"]);
    CHECK(replayed["digest"] == before["digest"]);
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("progress comes at most four times a second and only rises, morphology reports too", "[hub][long]") {
  Hub hub(longOptions());
  TestClient a(hub);
  a.result("session.create", kCreatePig);
  const auto start = Clock::now();
  // Sixty-four whole-volume passes (the most one morph takes), so that it lasts well beyond the
  // first report's 250 ms: sixteen took 0.25 s on a quiet machine once the march got cheaper
  // (2026-11-25) and then ended before any report.
  sendLong(a, 7, "volume.morph", {{"kind", "dilate"}, {"radius", 64}});
  const json r = responseTo(a, 7);
  INFO(r.dump());
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  REQUIRE(r.contains("result"));
  std::vector<double> fractions;
  for (std::size_t i = 0; i < a.link->size(); ++i) {
    const auto m = a.link->at(i);
    if (isNotification(m, "op.progress") && std::get<json>(m)["params"]["request"] == 7)
      fractions.push_back(std::get<json>(m)["params"]["fraction"].get<double>());
  }
  INFO(seconds << " s, " << fractions.size() << " reports");
  REQUIRE(!fractions.empty());
  CHECK(double(fractions.size()) <= 1 + seconds * 4);
  for (std::size_t i = 1; i < fractions.size(); ++i) CHECK(fractions[i] >= fractions[i - 1]);
  CHECK(fractions.back() <= 1.0);
}

TEST_CASE("a request over max_op_voxels is refused with -32004 naming the limit, before anything runs", "[hub][long]") {
  HubOptions o = longOptions();
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreatePig);
  const json before = a.result("session.stats");
  const json smooth = a.call("tool.apply", {{"tool", "smooth"}, {"global", true}, {"iterations", 100000}});
  INFO(smooth.dump());
  CHECK(smooth["error"]["code"] == -32004);
  CHECK(smooth["error"]["data"]["limit"] == "max_op_voxels");
  CHECK(smooth["error"]["data"]["value"].get<double>() > o.limits.maxOpVoxels);
  CHECK(smooth["error"]["message"].get<std::string>().find("max_op_voxels") != std::string::npos);

  // A stroke of radius 1024 with xyz symmetry and 256 dabs: each dab's region is the whole
  // 128^3 domain, eight times over.
  const std::uint64_t stroke = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 1024}, {"symmetry", {"x", "y", "z"}}})["stroke"];
  json dabs = json::array();
  for (int i = 0; i < 256; ++i) dabs.push_back({{"center", {64, 64, 64}}});
  const json big = a.call("stroke.dabs", {{"stroke", stroke}, {"dabs", dabs}});
  INFO(big.dump().substr(0, 300));
  CHECK(big["error"]["code"] == -32004);
  CHECK(big["error"]["data"]["limit"] == "max_op_voxels");
  const json after = a.result("session.stats");
  CHECK(after["revision"] == before["revision"]);
  CHECK(after["digest"] == before["digest"]);
}

TEST_CASE("other sessions are served while long operations run in as many sessions as there are workers", "[hub][long]") {
  Hub hub(longOptions());
  TestClient a(hub), c(hub), b(hub);
  a.result("session.create", kCreatePig);
  c.result("session.create", kCreatePig);
  b.result("session.create", kCreatePig);
  sendLong(a, 9, "tool.apply", kLongSmooth);
  sendLong(c, 9, "volume.morph", {{"kind", "close"}, {"radius", 60}});
  waitProgress(a, 9);
  waitProgress(c, 9);
  // Renders use the same engine pool as the smoothing; edits of b run on its own strand. The
  // long operations take hours unless cancelled, and are cancelled only after b's rounds: each
  // of b's answers (waited for kWait at most) comes while both still run, whatever the
  // machine's load, and never if they held b up (no time is bounded: that is speed).
  for (int i = 0; i < 3; ++i) {
    b.result("render.frame", {{"camera", {{"eye", {64, 80, 300}}, {"target", {64, 64, 64}}}}, {"width", 256}, {"height", 256}, {"format", "png"}});
    b.result("tool.apply", kBlob);
    b.result("volume.morph", {{"kind", "dilate"}, {"radius", 1}});
  }
  // Still running: each answers only now, to its cancel.
  CHECK(a.result("op.cancel")["cancelled"] == true);
  CHECK(c.result("op.cancel")["cancelled"] == true);
  CHECK(responseTo(a, 9)["error"]["code"] == -32016);
  CHECK(responseTo(c, 9)["error"]["code"] == -32016);
}

TEST_CASE("shutdown cancels a long operation and returns within seconds, keeping every acknowledged edit", "[hub][long]") {
  const auto dir = scratch("shutdown");
  HubOptions o = longOptions();
  o.dataDir = dir;
  json created, acknowledged;
  {
    Hub hub(o);
    TestClient a(hub);
    created = a.result("session.create", kCreatePig);
    a.result("tool.apply", kBlob);
    acknowledged = a.result("session.stats");
    sendLong(a, 11, "tool.apply", kLongSmooth);
    waitProgress(a, 11);
    const auto start = Clock::now();
    hub.shutdown();
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    // The hub waits 2 s for running edits, as long again for the snapshots (hub.cpp,
    // kShutdownWait): 10 s is the server's promise for SIGTERM, and room for a loaded machine.
    CHECK(seconds < 10);
    const json answer = responseTo(a, 11);
    CHECK(answer["error"]["code"] == -32016);
  }
  {
    Hub hub(o);
    TestClient b(hub);
    b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
    const json back = b.result("session.stats");
    CHECK(back["revision"] == acknowledged["revision"]);
    CHECK(back["digest"] == acknowledged["digest"]);
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("volume.load of a file with another band width is refused, the undo history stays", "[hub]") {
  Hub hub(longOptions());
  TestClient a(hub);
  a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  const json before = a.result("session.stats");
  const Bytes file = saveVolume(makeSolid(SolidKind::Sphere, {64, 64, 64}, 5.0f));
  const int id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", file.size()}}}}.dump());
  a.hub.binary(a.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
  const json r = responseTo(a, id);
  INFO(r.dump());
  CHECK(r["error"]["code"] == -32006);
  CHECK(r["error"]["data"]["field"] == "file");
  const json after = a.result("session.stats");
  CHECK(after["revision"] == before["revision"]);
  CHECK(after["digest"] == before["digest"]);
  CHECK(after["can_undo"] == true);
}

TEST_CASE("with --fsync-ms, records an append did not sync are synced by a timer within the interval", "[hub][durability]") {
  const auto dir = scratch("fsync");
  HubOptions o = longOptions();
  o.dataDir = dir;
  o.fsyncInterval = std::chrono::milliseconds(1000);
  std::mutex mutex;
  std::condition_variable cv;
  int synced = 0;
  o.events.journalSynced = [&] {
    const std::lock_guard lock(mutex);
    ++synced;
    cv.notify_all();
  };
  {
    Hub hub(o);
    TestClient a(hub);
    a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
    // Four edits sent at once: their appends follow one another on the session's strand, each
    // within the interval of the sync before unless every one of them waited over a second for
    // a worker, and only the timer syncs such an append. (One edit after another's answer, as
    // here before, came later than a 150 ms interval on a loaded machine: synced at once, so
    // the timer had nothing to do, 4 of 15 runs beside three busy loops.)
    for (int i = 0; i < 4; ++i) sendLong(a, 20 + i, "tool.apply", {{"tool", "add_blob"}, {"center", {24 + 4 * i, 54, 32}}});
    for (int i = 0; i < 4; ++i) REQUIRE(responseTo(a, 20 + i).contains("result"));
    std::unique_lock lock(mutex);
    // The timer's first run after the interval; kWait: a loaded machine may run it late.
    CHECK(cv.wait_for(lock, kWait, [&] { return synced > 0; }));
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("parallel joins of a session at rest load it once, a full server refuses before loading", "[hub][durability]") {
  const auto dir = scratch("joins");
  HubOptions o = longOptions();
  o.dataDir = dir;
  json created, other;
  {
    Hub hub(o);
    TestClient a(hub), b(hub);
    created = a.result("session.create", kCreatePig);
    for (int i = 0; i < 20; ++i) a.result("tool.apply", kBlob);
    other = b.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
  }
  std::mutex mutex;
  int loads = 0;
  o.events.log = [&](const std::string& line) {
    const std::lock_guard lock(mutex);
    if (line.find(": loaded from ") != std::string::npos) ++loads;
  };
  {
    Hub hub(o);
    std::vector<std::unique_ptr<TestClient>> clients;
    for (int i = 0; i < 4; ++i) clients.push_back(std::make_unique<TestClient>(hub));
    for (auto& c : clients)
      c->hub.text(c->client, json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "session.join"},
                                  {"params", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}}}}
                                 .dump());
    std::set<int> ids;
    for (auto& c : clients) {
      const json r = responseTo(*c, 1);
      INFO(r.dump().substr(0, 300));
      REQUIRE(r.contains("result"));
      ids.insert(r["result"]["client"].get<int>());
    }
    CHECK(ids.size() == 4);  // four clients of one session
    CHECK(hub.sessionCount() == 1);
    const std::lock_guard lock(mutex);
    CHECK(loads == 1);
  }
  {
    o.limits.maxSessions = 1;
    Hub hub(o);
    TestClient a(hub), b(hub);
    a.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
    const json full = b.call("session.join", {{"session", other["session"]}, {"token", other["token"]}, {"view", "none"}});
    CHECK(full["error"]["code"] == -32004);
    CHECK(full["error"]["data"]["limit"] == "max_sessions");
    const std::lock_guard lock(mutex);
    CHECK(loads == 2);  // one more: the first join of this hub
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("a frames client that moves between sessions while its frames render (run under TSan: tests/tsan.sh)", "[hub]") {
  HubOptions o = longOptions();
  o.stillDelay = std::chrono::milliseconds(1);
  Hub hub(o);
  TestClient a(hub), b(hub), mover(hub);
  const json s1 = a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
  const json s2 = b.result("session.create", {{"size", {64, 64, 64}}, {"solid", "box"}, {"view", "none"}});
  const json camera = {{"eye", {32, 40, 150}}, {"target", {32, 32, 32}}};
  for (int round = 0; round < 6; ++round) {
    const json& s = round % 2 ? s2 : s1;
    mover.result("session.join", {{"session", s["session"]}, {"token", s["token"]}, {"view", "none"}});
    mover.result("view.set", {{"mode", "frames"}, {"camera", camera}, {"width", 64}, {"height", 48}});
    (round % 2 ? b : a).result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
    mover.result("session.leave");
  }
  // Frames of a session it left never follow it into the next one's state: it still renders.
  mover.result("session.join", {{"session", s1["session"]}, {"token", s1["token"]}, {"view", "none"}});
  const std::size_t mark = mover.link->size();
  mover.result("view.set", {{"mode", "frames"}, {"camera", camera}, {"width", 64}, {"height", 48}});
  mover.link->waitFor([](const auto& m) { return std::holds_alternative<Bytes>(m); }, mark);
}

// A stress test: the race it guards (an edit dispatched just before `stopping` reaching the
// strand after the shutdown snapshot) is a window of microseconds; it did not show in 4 runs
// before the fix, which closes it by construction (the snapshot task closes the session, and
// persist() refuses a change it cannot journal).
TEST_CASE("edits racing shutdown: every acknowledged one is journaled", "[hub][durability]") {
  const auto dir = scratch("late-edits");
  HubOptions o = longOptions();
  o.dataDir = dir;
  o.limits.maxRequestsPerSecond = 1000000;
  json created;
  std::uint64_t acknowledged = 0;
  {
    Hub hub(o);
    TestClient a(hub);
    created = a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
    // Keep up to 32 edits in flight while the hub shuts down. The shutdown starts 30 ms after the
    // first edit is answered, not after the first is sent: on a loaded machine the first batch
    // could still be waiting for a core 30 ms after it was sent, and then nothing was
    // acknowledged, which proves nothing about the race.
    std::thread stopper;
    int sent = 0;
    for (int round = 0; round < 40; ++round) {
      for (int k = 0; k < 32; ++k) {
        const double x = 20 + (sent % 24);
        sendLong(a, 1000 + sent++, "tool.apply", {{"tool", "add_blob"}, {"center", {x, 54, 32}}, {"radius", 3}});
      }
      if (round == 0) {
        REQUIRE(responseTo(a, 1000).contains("result"));
        stopper = std::thread([&] {
          std::this_thread::sleep_for(std::chrono::milliseconds(30));
          hub.shutdown();
        });
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    stopper.join();
    // Requests that came after the workers stopped get no answer (the network layer closes the
    // connections then): only what was answered counts.
    for (std::size_t i = 0; i < a.link->size(); ++i) {
      const auto m = a.link->at(i);
      const json* r = std::get_if<json>(&m);
      if (r && r->contains("result") && r->contains("id") && (*r)["id"].is_number() && (*r)["id"].get<int>() >= 1000)
        acknowledged = std::max<std::uint64_t>(acknowledged, (*r)["result"]["revision"].get<std::uint64_t>());
    }
    CHECK(acknowledged > 0);
  }
  Hub hub(o);
  TestClient b(hub);
  const json joined = b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
  INFO("acknowledged up to revision " << acknowledged);
  CHECK(joined["revision"].get<std::uint64_t>() >= acknowledged);
  std::filesystem::remove_all(dir);
}

TEST_CASE("session.stats measures off the strand: an edit sent after it is answered before it", "[hub]") {
  // a's stats request reads the session's counters on the strand, then measures its snapshot on
  // a worker, whose answer is held (GateLink) until b's edit, sent after that, is answered.
  // Measured on the strand, the held answer would hold the strand and the edit would wait for
  // it. No timing decides it: the stats request is held before the edit is sent.
  Hub hub(longOptions());
  const auto aLink = std::make_shared<GateLink>();
  const auto a = hub.connect(aLink, "a");
  const OpenOnExit open{{aLink}};
  TestClient b(hub);
  hub.text(a, json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "session.create"}, {"params", kCreatePig}}.dump());
  const json created = std::get<json>(aLink->at(aLink->waitFor([](const auto& m) { return isResponse(m, 1); })))["result"];
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
  for (int round = 0; round < 3; ++round) {
    const int statsId = 700 + round;
    aLink->gateAt(statsId);
    hub.text(a, json{{"jsonrpc", "2.0"}, {"id", statsId}, {"method", "session.stats"}, {"params", json::object()}}.dump());
    aLink->waitUntil(aLink->atResult);
    const json edit = b.call("tool.apply", kBlob);  // on the surface: every one changes the volume
    REQUIRE(edit.contains("result"));
    aLink->set(aLink->resultOpen);
    const json stats = std::get<json>(aLink->at(aLink->waitFor([&](const auto& m) { return isResponse(m, statsId); })));
    REQUIRE(stats.contains("result"));
    INFO("round " << round);
    CHECK(stats["result"]["revision"].get<std::uint64_t>() < edit["result"]["revision"].get<std::uint64_t>());
  }
  hub.disconnect(a);
}
