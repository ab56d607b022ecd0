// Names, colours and presence through the hub (PROTOCOL.md, "Presence"): validation refusals,
// others-only forwarding, a view client's brush dropped, the rate bound and latest-wins under
// many updates, the leave, and that presence never becomes an edit. Driven through
// hub_support.hpp; the rate checks count deliveries against the wall time they took, which
// the coalescer's 50 ms interval bounds from above whatever the machine's load.
#include <catch2/catch.hpp>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/hub.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;

namespace {

HubOptions presenceOptions() {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 64;
  return o;
}

const json kCreate = {{"size", {32, 32, 32}}, {"solid", "sphere"}, {"view", "none"}};

json brushAt(double x, bool active = false) {
  return {{"tool", "add_blob"}, {"radius", 6}, {"point", {x, 20, 16}}, {"normal", {0, 2, 0}}, {"active", active}};
}
const json kCamera = {{"eye", {16, 16, 80}}, {"target", {16, 16, 16}}};

std::vector<json> presences(TestClient& t) {
  std::vector<json> out;
  for (std::size_t i = 0; i < t.link->size(); ++i)
    if (const auto m = t.link->at(i); isNotification(m, "presence")) out.push_back(std::get<json>(m)["params"]);
  return out;
}

std::string fieldOf(const json& response) { return response["error"]["data"].value("field", ""); }

void sendNotification(TestClient& t, const json& params) {
  t.hub.text(t.client, json{{"jsonrpc", "2.0"}, {"method", "presence"}, {"params", params}}.dump());
}

}  // namespace

TEST_CASE("names are trimmed and checked, colours differ within a session and are reused", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub), b(hub), c(hub), bad(hub);
  json params = kCreate;
  params["name"] = "  Ada \u00e9\u00e9  ";
  const json created = a.result("session.create", params);
  CHECK(created["clients"] == json::array({{{"client", 1}, {"read_only", false}, {"name", "Ada \u00e9\u00e9"}, {"color", "#e6194b"}}}));

  const json join = {{"session", created["session"]}, {"token", created["token"]}};
  for (const json& name : {json(""), json("   "), json(std::string(65, 'x')), json("a\u0007b"), json("a\u202eb"),
                           json("a\u0085b"), json(42), json(nullptr)}) {
    json p = join;
    p["name"] = name;
    const json r = bad.call("session.join", p);
    INFO(r.dump());
    CHECK(r["error"]["code"] == -32602);
    CHECK(fieldOf(r) == "name");
  }
  // 64 characters of two bytes each: code points count, not bytes.
  std::string longest;
  for (int i = 0; i < 64; ++i) longest += "\u00e9";
  json withLongest = join;
  withLongest["name"] = longest;
  const json joined = b.result("session.join", withLongest);
  CHECK(joined["clients"][1] == json{{"client", 2}, {"read_only", false}, {"name", longest}, {"color", "#3cb44b"}});
  const json third = c.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}});
  CHECK(third["clients"][2] == json{{"client", 3}, {"read_only", true}, {"name", "Sculptor 3"}, {"color", "#4363d8"}});
  const std::size_t note = a.link->waitFor([](const auto& m) {
    return isNotification(m, "session.clients") && std::get<json>(m)["params"]["clients"].size() == 3;
  });
  CHECK(std::get<json>(a.link->at(note))["params"]["clients"] == third["clients"]);

  // The colour of a client that left goes to the next one.
  b.result("session.leave");
  const json again = bad.result("session.join", join);
  CHECK(again["client"] == 4);
  CHECK(again["clients"].back()["color"] == "#3cb44b");
}

TEST_CASE("presence is checked strictly, a refusal forwards nothing", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub), b(hub);
  CHECK(a.error("presence", {{"camera", kCamera}}) == -32009);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});

  const auto refused = [&](const json& params, const std::string& field) {
    const json r = a.call("presence", params);
    INFO(r.dump());
    CHECK(r["error"]["code"] == -32602);
    CHECK(fieldOf(r) == field);
  };
  refused({{"pointer", {1, 2, 3}}}, "pointer");
  refused({{"brush", 3}}, "brush");
  for (const char* key : {"tool", "radius", "point", "normal", "active"}) {
    json brush = brushAt(10);
    brush.erase(key);
    refused({{"brush", brush}}, "brush");
  }
  const auto withBrush = [&](const char* key, const json& value) {
    json brush = brushAt(10);
    brush[key] = value;
    return json{{"brush", brush}};
  };
  refused(withBrush("tool", "hammer"), "brush");
  refused(withBrush("radius", 0.1), "brush");
  refused(withBrush("radius", 2000), "brush");
  refused(withBrush("point", {1, 2}), "brush");
  refused(withBrush("point", {1e7, 0, 0}), "brush");
  refused(withBrush("normal", {0, 0, 0}), "brush");
  refused(withBrush("active", 1), "brush");
  refused(withBrush("extra", 1), "brush");
  refused({{"camera", {{"eye", {1, 2, 3}}, {"target", {1, 2, 3}}}}}, "camera");
  refused({{"camera", {{"eye", {1, 2, 3}}, {"target", {4, 5, 6}}, {"fov", 200}}}}, "camera");
  refused({{"camera", {{"eye", {1, 2, 3}}, {"target", {4, 5, 6}}, {"width", 10}}}}, "camera");
  // A refused notification gets no answer either; then one valid presence is what arrives.
  sendNotification(a, {{"brush", 1}});
  CHECK(a.result("presence", {{"camera", kCamera}}) == json::object());
  b.link->waitFor([](const auto& m) { return isNotification(m, "presence"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  CHECK(presences(b).size() == 1);
  int responses = 0;
  for (std::size_t i = 0; i < a.link->size(); ++i) {
    const auto m = a.link->at(i);
    CHECK_FALSE(isNotification(m, "presence"));
    if (const json* j = std::get_if<json>(&m); j && j->contains("id")) ++responses;
  }
  CHECK(responses == a.nextId - 1);  // none to the notification
}

TEST_CASE("presence goes to the others only, canonical, a view client's brush is dropped", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub), b(hub), v(hub);
  json params = kCreate;
  params["name"] = "Ada";
  const json created = a.result("session.create", params);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  v.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}});

  a.result("presence", {{"brush", brushAt(12.5, true)}, {"camera", kCamera}});
  for (TestClient* t : {&b, &v}) {
    const std::size_t i = t->link->waitFor([](const auto& m) { return isNotification(m, "presence"); });
    CHECK(std::get<json>(t->link->at(i))["params"] ==
          json{{"client", 1},
               {"name", "Ada"},
               {"color", "#e6194b"},
               {"brush", {{"tool", "add_blob"}, {"radius", 6.0}, {"point", {12.5, 20.0, 16.0}}, {"normal", {0.0, 1.0, 0.0}},
                          {"active", true}}},
               {"camera", {{"eye", {16.0, 16.0, 80.0}}, {"target", {16.0, 16.0, 16.0}}, {"up", {0.0, 1.0, 0.0}}, {"fov", 40.0}}}});
  }
  v.result("presence", {{"brush", brushAt(3)}, {"camera", kCamera}});
  for (TestClient* t : {&a, &b}) {
    const std::size_t i = t->link->waitFor([](const auto& m) {
      return isNotification(m, "presence") && std::get<json>(m)["params"]["client"] == 3;
    });
    const json got = std::get<json>(t->link->at(i))["params"];
    CHECK_FALSE(got.contains("brush"));
    CHECK(got["camera"]["eye"] == json{16.0, 16.0, 80.0});
    CHECK(got["name"] == "Sculptor 3");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  for (const json& p : presences(a)) CHECK(p["client"] != 1);
  for (const json& p : presences(v)) CHECK(p["client"] != 3);
  // Never an edit: no revision, no undo step.
  const json stats = a.result("session.stats");
  CHECK(stats["revision"] == 0);
  CHECK(stats["can_undo"] == false);
}

TEST_CASE("many presence updates reach the others at most every 50 ms, the newest last", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});

  SECTION("a burst: a few deliveries, the last one the newest") {
    const auto start = std::chrono::steady_clock::now();
    // Fewer than max_pending_messages (64), so that none is refused as busy.
    for (int i = 1; i <= 50; ++i) sendNotification(a, {{"brush", brushAt(i / 100.0 * 6)}});
    a.result("session.stats");  // every notification before it was handled
    const double sent = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    b.link->waitFor([](const auto& m) {
      return isNotification(m, "presence") && std::get<json>(m)["params"]["brush"]["point"][0] == 3.0;
    });
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const std::vector<json> got = presences(b);
    INFO("sent in " << sent << " s, " << got.size() << " delivered in " << elapsed << " s");
    CHECK(got.size() <= std::size_t(elapsed / 0.05) + 1);
    CHECK(got.back()["brush"]["point"][0] == 3.0);
    for (std::size_t i = 1; i < got.size(); ++i)
      CHECK(got[i]["brush"]["point"][0].get<double>() > got[i - 1]["brush"]["point"][0].get<double>());
  }
  SECTION("60 Hz: deliveries come while the updates go on, never more than the interval allows") {
    // At least half a second of updates, and on until b has one that is neither the first nor
    // the newest sent: a coalescer that held the newest until the updates paused (a debounce)
    // delivers none while they go on. Not a count over a time (a loaded machine that stalls
    // this thread bunches the updates): the updates go on until it comes, ten seconds at most.
    const auto start = std::chrono::steady_clock::now();
    int sent = 0;
    const auto between = [&] {
      for (const json& p : presences(b))
        if (const double x = p["brush"]["point"][0].get<double>(); x > 1 && x < sent) return true;
      return false;
    };
    while (sent < 30 || (!between() && sent < 600)) {
      ++sent;
      sendNotification(a, {{"brush", brushAt(sent)}});
      std::this_thread::sleep_until(start + sent * std::chrono::microseconds(16'667));
    }
    b.link->waitFor([&](const auto& m) {
      return isNotification(m, "presence") && std::get<json>(m)["params"]["brush"]["point"][0] == double(sent);
    });
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::vector<json> got = presences(b);
    INFO(got.size() << " delivered in " << elapsed << " s, " << sent << " sent");
    CHECK(got.size() <= std::size_t(elapsed / 0.05) + 1);
    CHECK(between());
    CHECK(got.size() >= 3);
  }
}

// Presence is handled by the thread that hands it over when its connection is idle (no hop to
// a worker); a message that only names "presence" is handed to the workers once parsed.
TEST_CASE("a presence on an idle connection is handled at once by the thread that hands it over", "[hub][presence]") {
  // One worker, so that a is idle when the presence is sent: the worker lets a's connection go
  // just after sending the answer to session.create, in the same task, and b's join, handed to
  // the worker's queue once that answer is here, runs after that task.
  HubOptions o = presenceOptions();
  o.workers = 1;
  Hub hub(o);
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  // Notifications of b's join may still reach a from the session's strand meanwhile: the
  // answer is looked for among what came after the mark, not assumed to be alone there.
  const auto answeredHere = [&](const json& request) {
    const std::size_t mark = a.link->size();
    hub.text(a.client, request.dump());
    const std::lock_guard lock(a.link->mutex);  // no waiting: the answer is there already
    for (std::size_t k = mark; k < a.link->messages.size(); ++k)
      if (isResponse(a.link->messages[k], request["id"])) return a.link->senders[k] == std::this_thread::get_id();
    return false;
  };
  CHECK(answeredHere({{"jsonrpc", "2.0"}, {"id", 50}, {"method", "presence"}, {"params", {{"camera", kCamera}}}}));
  CHECK(answeredHere({{"jsonrpc", "2.0"}, {"id", 51}, {"method", "presence"}, {"params", {{"brush", 3}}}}));
  CHECK(std::get<json>(a.link->at(a.link->waitFor([](const auto& m) { return isResponse(m, 51); })))["error"]["code"] == -32602);
  // The valid one reached b.
  b.link->waitFor([](const auto& m) { return isNotification(m, "presence"); });
  // A slow method (one that may load a session) whose text says "presence" is handled by a
  // worker, even its refusal of bad params (which session.join checks before any work).
  const std::size_t mark = a.link->size();
  hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", "presence"}, {"method", "session.join"}, {"params", {{"x", 1}}}}.dump());
  const std::size_t at = a.link->waitFor([](const auto& m) { return isResponse(m, "presence"); }, mark);
  const std::lock_guard lock(a.link->mutex);
  CHECK(std::get<json>(a.link->messages[at])["error"]["code"] == -32602);
  CHECK(a.link->senders[at] != std::this_thread::get_id());
}

TEST_CASE("a client that leaves is gone for the others, and its presence with it", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  {
    TestClient b(hub);
    b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
    b.result("presence", {{"camera", kCamera}});
    a.link->waitFor([](const auto& m) { return isNotification(m, "presence"); });
  }
  const std::size_t gone = a.link->waitFor([](const auto& m) {
    return isNotification(m, "presence") && std::get<json>(m)["params"].contains("gone");
  });
  CHECK(std::get<json>(a.link->at(gone))["params"] == json{{"client", 2}, {"gone", true}});
  a.link->waitFor([](const auto& m) {
    return isNotification(m, "session.clients") && std::get<json>(m)["params"]["clients"].size() == 1;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  CHECK(presences(a).size() == 2);
}

TEST_CASE("a fork keeps the caller's display name", "[hub][presence]") {
  Hub hub(presenceOptions());
  TestClient a(hub);
  json params = kCreate;
  params["name"] = "Ada";
  a.result("session.create", params);
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {16, 26, 16}}, {"radius", 4}});
  const json fork = a.result("session.fork", json::object());
  REQUIRE(fork["clients"].size() == 1);
  CHECK(fork["clients"][0]["name"] == "Ada");
}
