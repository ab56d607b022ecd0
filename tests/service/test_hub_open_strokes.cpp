// Open strokes through the hub (issue 31 item 4): a stroke left without a message for
// stroke_idle is ended at the session's next change as stroke.end would (journaled: a recovery
// has it closed too), and its client hears -32011 for its next dabs.
#include <catch2/catch.hpp>

#include <chrono>
#include <filesystem>
#include <thread>

#include <nlohmann/json.hpp>

#include "engine/thread_pool.hpp"
#include "service/hub.hpp"
#include "service/session_store.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;
namespace fs = std::filesystem;

TEST_CASE("an open stroke idle for stroke_idle is ended at the next change, journaled as stroke.end", "[hub][strokes]") {
  const fs::path dir = fs::temp_directory_path() / "marzipan-hub-open-strokes";
  fs::remove_all(dir);
  HubOptions o = twoWorkerOptions(dir);
  // The hub's stroke clock is the steady clock (a test cannot set it through the hub), so the
  // sleeps decide which stroke is idle at B's second dabs: A's for at least 3.1 s (the two
  // sleeps), more than stroke_idle whatever the load. What the load may lengthen has 1.4 s to
  // spare: A's idle time at B's first dabs (1.5 s and the answers' time), and B's between its
  // two dabs (1.6 s and the answers' time), each less than stroke_idle (3 s).
  o.limits.strokeIdle = std::chrono::seconds(3);
  std::string id;
  {
    Hub hub(o);
    TestClient a(hub), b(hub);
    const json created = a.result("session.create", {{"size", {48, 48, 48}}, {"solid", "sphere"}, {"view", "none"}});
    id = created["session"];
    b.result("session.join", {{"session", id}, {"token", created["token"]}, {"view", "none"}});
    const std::uint64_t idle = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 4}})["stroke"];
    const std::uint64_t busy = b.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 4}})["stroke"];
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    b.result("stroke.dabs", {{"stroke", busy}, {"dabs", {{{"center", {40, 24, 24}}}}}});
    std::this_thread::sleep_for(std::chrono::milliseconds(1600));
    // A's stroke had no message for 3.1 s, B's for 1.6 s: B's next change ends A's only.
    b.result("stroke.dabs", {{"stroke", busy}, {"dabs", {{{"center", {40, 26, 24}}}}}});
    const json refused = a.call("stroke.dabs", {{"stroke", idle}, {"dabs", {{{"center", {8, 24, 24}}}}}});
    INFO(refused.dump());
    CHECK(refused["error"]["code"] == -32011);
    CHECK(refused["error"]["message"].get<std::string>().find("has ended") != std::string::npos);
    // Ending it again, as the client may, is answered as before.
    CHECK(a.result("stroke.end", {{"stroke", idle}})["revision"] == 2);
    b.result("stroke.dabs", {{"stroke", busy}, {"dabs", {{{"center", {40, 28, 24}}}}}});
  }
  // The journal with the stroke_end that followed B's change replays to the same revision.
  SessionStore store(dir);
  Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  CHECK(r.session->revision() == 3);
  fs::remove_all(dir);
}
