// The hub without sockets: every method's success path and its refusals, two clients on one
// session, undo digests, splat deltas against a fresh full buffer, frames, uploads, limits and
// idle unloading, driven through hub_support.hpp (a CaptureLink records what the hub sends;
// every wait times out, so a hang fails the test instead of the run).
#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <cctype>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <variant>

#include <nlohmann/json.hpp>

#include "engine/solids.hpp"
#include "engine/support.hpp"
#include "engine/splats.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/rpc.hpp"
#include "protocol/cpp/splats.hpp"
#include "engine/measures.hpp"
#include "service/hub.hpp"
#include "service/measures_json.hpp"
#include "service/session.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;
using Bytes = std::vector<std::uint8_t>;

namespace {

protocol::FrameHeader headerOf(const Bytes& b) {
  const auto d = protocol::decodeFrameHeader(b);
  REQUIRE(d);
  return d.frame->header;
}

bool isFrame(const std::variant<json, Bytes>& m, protocol::FrameKind kind) {
  const Bytes* b = std::get_if<Bytes>(&m);
  return b && headerOf(*b).kind == kind;
}

std::span<const std::uint8_t> payloadOf(const Bytes& b) { return {b.data() + protocol::kFrameHeaderBytes, b.size() - protocol::kFrameHeaderBytes}; }

HubOptions smallOptions() {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  o.stillDelay = std::chrono::milliseconds(50);
  return o;
}

const json kCreate64 = {{"size", {64, 64, 64}}, {"solid", "sphere"}};

// The splat points a client holds after applying full buffers and deltas, per brick.
using Held = std::map<std::array<int, 3>, std::vector<std::uint64_t>>;

// The blocks of a splat buffer in order, a brick without points (N = 0) included.
std::vector<std::pair<std::array<int, 3>, std::vector<std::uint64_t>>> blocksOf(const Bytes& frame) {
  const auto payload = payloadOf(frame);
  std::vector<std::pair<std::array<int, 3>, std::vector<std::uint64_t>>> out;
  // Walk the MZSP blocks directly: 16-byte header, then per brick 8 bytes + 8 per point.
  std::size_t at = 16;
  while (at < payload.size()) {
    const auto u16 = [&](std::size_t o) { return int(payload[o] | payload[o + 1] << 8); };
    const std::array<int, 3> brick{u16(at), u16(at + 2), u16(at + 4)};
    const int n = u16(at + 6);
    std::vector<std::uint64_t> points(std::size_t(n), 0);
    for (int i = 0; i < n; ++i)
      for (int b = 0; b < 8; ++b) points[std::size_t(i)] |= std::uint64_t(payload[at + 8 + 8 * std::size_t(i) + std::size_t(b)]) << (8 * b);
    out.emplace_back(brick, std::move(points));
    at += 8 + 8 * std::size_t(n);
  }
  return out;
}

void applySplats(Held& held, const Bytes& frame) {
  if (headerOf(frame).kind == protocol::FrameKind::SplatsFull) held.clear();
  for (auto& [brick, points] : blocksOf(frame)) {
    if (points.empty()) held.erase(brick);
    else held[brick] = std::move(points);
  }
}

// PNG: the IHDR chunk; JPEG: the first SOFn marker.
std::pair<int, int> imageSize(std::span<const std::uint8_t> f) {
  if (f.size() > 24 && f[0] == 0x89 && f[1] == 'P')
    return {int(f[16] << 24 | f[17] << 16 | f[18] << 8 | f[19]), int(f[20] << 24 | f[21] << 16 | f[22] << 8 | f[23])};
  if (f.size() > 4 && f[0] == 0xFF && f[1] == 0xD8) {
    std::size_t i = 2;
    while (i + 9 < f.size()) {
      if (f[i] != 0xFF) return {0, 0};
      const int marker = f[i + 1];
      const std::size_t len = std::size_t(f[i + 2] << 8 | f[i + 3]);
      if (marker >= 0xC0 && marker <= 0xC3) return {int(f[i + 7] << 8 | f[i + 8]), int(f[i + 5] << 8 | f[i + 6])};
      i += 2 + len;
    }
  }
  return {0, 0};
}

}  // namespace

TEST_CASE("session.create answers with ids, limits and the version, then a full splat buffer", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  const json r = a.result("session.create", kCreate64);
  CHECK(r["session"].get<std::string>().size() == 22);
  CHECK(r["token"].get<std::string>().size() == 43);
  CHECK(r["view_token"].get<std::string>() != r["token"].get<std::string>());
  CHECK(r["size"] == json({64, 64, 64}));
  CHECK(r["revision"] == 0);
  CHECK(r["client"] == 1);
  CHECK(r["protocol"] == json({{"major", 1}, {"minor", 7}}));
  CHECK(r["limits"]["max_grid_side"] == 128);
  CHECK(r["limits"]["max_dabs"] == 256);
  CHECK(r["read_only"] == false);
  CHECK(r["clients"] == json::array({{{"client", 1}, {"read_only", false}, {"name", "Sculptor 1"}, {"color", "#e6194b"}}}));
  const std::size_t full = a.link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsFull); });
  const Bytes frame = std::get<Bytes>(a.link->at(full));
  CHECK(headerOf(frame).requestId == 0);
  std::uint16_t version = 0;
  const auto decoded = decodeSplats(payloadOf(frame), &version);
  CHECK(version == 1);  // the client did not opt into colour (splats: 2)
  std::size_t points = 0;
  for (const auto& b : decoded) points += b.points.size();
  // A sphere of radius 0.35 * 64 = 22.4 has about 4 pi r^2 ~ 6300 surface voxels.
  CHECK(points > 4000);
  CHECK(points < 12000);
  CHECK(hub.sessionCount() == 1);
}

TEST_CASE("session.stats answers PROTOCOL.md's keys, its measures in batch --stats's shape", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  const json r = a.result("session.stats");
  std::set<std::string> keys;
  for (const auto& [key, value] : r.items()) keys.insert(key);
  CHECK(keys == std::set<std::string>{"session", "size", "revision", "digest", "clients", "inside_volume", "surface_area",
                                      "components", "bounds", "gradient_error", "memory_bytes", "history_bytes",
                                      "can_undo", "can_redo"});
  // The same measures of the same solid through the one builder batch --stats uses.
  ThreadPool pool(1);
  json expected = json::object();
  putMeasures(expected, measure(makeSolid(SolidKind::Sphere, {64, 64, 64}, Volume::kDefaultBand, pool)));
  for (const auto& [key, value] : expected.items()) {
    INFO(key);
    CHECK(r[key] == value);
  }
  CHECK(r["bounds"]["empty"] == false);
  CHECK(r["bounds"]["lo"].size() == 3);
  CHECK(r["components"] == 1);
  CHECK(r["size"] == json({64, 64, 64}));
  CHECK(r["clients"] == json::array({{{"client", 1}, {"read_only", false}, {"name", "Sculptor 1"}, {"color", "#e6194b"}}}));
}

TEST_CASE("the envelope's refusals carry the right codes and never close", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  CHECK(a.rawResponse("{\"jsonrpc\":\"2.0\",\"id\":1,", nullptr)["error"]["code"] == -32700);
  CHECK(a.rawResponse("[{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"session.stats\"}]", nullptr)["error"]["code"] == -32600);
  CHECK(a.rawResponse(R"({"jsonrpc":"1.0","id":2,"method":"session.stats"})", 2)["error"]["code"] == -32600);
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":3,"method":"session.stats","extra":1})", 3)["error"]["code"] == -32600);
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":4,"method":"volume.explode"})", 4)["error"]["code"] == -32601);
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":5,"method":"session.stats","params":[1]})", 5)["error"]["data"]["field"] ==
        "params");
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":"s","method":"splats.get"})", "s")["error"]["code"] == -32600);
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":6,"method":"session.create","params":{"size":[64,64,64],"solid":"sphere","solid":"box"}})", nullptr)["error"]["code"] == -32700);
  CHECK(a.rawResponse(R"({"jsonrpc":"2.0","id":7,"method":"tool.apply","params":{"tool":"add_blob","center":[NaN,0,0]}})", nullptr)["error"]["code"] == -32700);
  CHECK(a.error("session.stats") == -32009);
  CHECK(a.error("tool.apply", {{"tool", "add_blob"}, {"center", {1, 2, 3}}}) == -32009);
  // A notification gets nothing back, not even an error.
  const std::size_t before = a.link->size();
  a.hub.text(a.client, R"({"jsonrpc":"2.0","method":"session.stats"})");
  a.result("session.create", kCreate64);
  for (std::size_t i = before; i < a.link->size(); ++i) {
    const auto m = a.link->at(i);
    if (const json* j = std::get_if<json>(&m)) CHECK(j->contains("result"));
  }
  CHECK(a.link->closeCode == 0);
}

TEST_CASE("session.create refuses bad params naming the field", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  const json tooBig = a.call("session.create", {{"size", {64, 64, 200}}, {"solid", "sphere"}});
  CHECK(tooBig["error"]["code"] == -32004);
  CHECK(tooBig["error"]["data"]["limit"] == "max_grid_side");
  const json small = a.call("session.create", {{"size", {4, 64, 64}}, {"solid", "sphere"}});
  CHECK(small["error"]["code"] == -32602);
  CHECK(small["error"]["data"]["field"] == "size");
  CHECK(a.call("session.create", {{"size", {64, 64, 64}}, {"solid", "cube"}})["error"]["data"]["field"] == "solid");
  CHECK(a.call("session.create", {{"size", {64, 64, 64.5}}, {"solid", "box"}})["error"]["data"]["field"] == "size");
  CHECK(a.call("session.create", {{"solid", "box"}})["error"]["data"]["field"] == "size");
  CHECK(a.call("session.create", {{"size", {64, 64, 64}}, {"solid", "box"}, {"protocol", 2}})["error"]["code"] == -32008);
  CHECK(a.call("session.create", {{"size", {64, 64, 64}}, {"solid", "box"}, {"session", "short"}})["error"]["data"]["field"] ==
        "session");
  // Under 128 random bits an id could be guessed, and join's answers tell whether it exists.
  CHECK(a.call("session.create", {{"size", {64, 64, 64}}, {"solid", "box"}, {"session", "abcdefghijklmnopqrstu"}})["error"]["data"]
            ["field"] == "session");
  CHECK(hub.sessionCount() == 0);
  a.result("session.create", kCreate64);
  CHECK(a.error("session.create", kCreate64) == -32010);
}

TEST_CASE("a proposed session id is used, and a taken one refused", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub), b(hub);
  json params = kCreate64;
  params["session"] = "my-own-session-id-0001";
  CHECK(a.result("session.create", params)["session"] == "my-own-session-id-0001");
  CHECK(b.error("session.create", params) == -32014);
}

TEST_CASE("two clients see each other's edits, a view token cannot edit", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub), b(hub), v(hub);
  const json created = a.result("session.create", kCreate64);
  CHECK(b.error("session.join", {{"session", created["session"]}, {"token", "wrong"}}) == -32002);
  CHECK(b.error("session.join", {{"session", "nosuchsession"}, {"token", created["token"]}}) == -32001);
  const json joined = b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  CHECK(joined["client"] == 2);
  CHECK(joined["read_only"] == false);
  CHECK(joined.count("token") == 0);
  CHECK(joined["view_token"] == created["view_token"]);  // an editor can share a view link
  a.link->waitFor([](const auto& m) {
    return isNotification(m, "session.clients") && std::get<json>(m)["params"]["clients"].size() == 2;
  });
  const json viewer = v.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}});
  CHECK(viewer["read_only"] == true);
  CHECK(viewer.count("view_token") == 0);

  const std::size_t mark = b.link->size();
  const json applied = a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 6}});
  CHECK(applied["revision"] == 1);
  const std::size_t note = b.link->waitFor([](const auto& m) { return isNotification(m, "session.changed"); }, mark);
  const json changed = std::get<json>(b.link->at(note))["params"];
  CHECK(changed["by"] == 1);
  CHECK(changed["cause"] == "tool");
  CHECK(changed["revision"] == 1);
  CHECK(changed["roi"] == applied["roi"]);
  const std::size_t delta = b.link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsDelta); }, note);
  CHECK(headerOf(std::get<Bytes>(b.link->at(delta))).revision == 1);

  CHECK(v.error("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}}) == -32007);
  CHECK(v.error("history.undo") == -32007);
  CHECK(v.result("session.stats")["revision"] == 1);
}

// Every editing method, with valid params, must get `code` on t's connection (-32009 outside
// a session, -32007 for a view client); nothing may change.
void expectNoEdits(TestClient& t, int code) {
  INFO("expected every edit refused with " << code);
  CHECK(t.error("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 6}}) == code);
  CHECK(t.error("volume.morph", {{"kind", "dilate"}, {"radius", 1}}) == code);
  CHECK(t.error("stroke.begin", {{"tool", "smooth"}}) == code);
  CHECK(t.error("stroke.dabs", {{"stroke", 1}, {"dabs", {{{"center", {32, 54, 32}}}}}}) == code);
  CHECK(t.error("stroke.end", {{"stroke", 1}}) == code);
  CHECK(t.error("history.undo") == code);
  CHECK(t.error("history.redo") == code);
  const std::vector<std::uint8_t> file = saveVolume(makeSolid(SolidKind::Box, {64, 64, 64}));
  const int id = t.nextId;
  CHECK(t.error("volume.load", {{"bytes", file.size()}}) == code);
  t.hub.binary(t.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
}

TEST_CASE("a refused session.create or session.join leaves the connection exactly as it was", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxClientsPerSession = 2;
  o.limits.maxSessions = 2;
  Hub hub(o);
  TestClient a(hub), v(hub), x(hub);
  json params = kCreate64;
  params["session"] = "refusals-session-id-0001";
  const json created = a.result("session.create", params);
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});  // something to undo
  v.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}});
  std::uint64_t revision = 1;

  SECTION("outside a session") {
    // The issue's reproduction: the session is full (-32003) and the joiner held the view token.
    CHECK(x.error("session.join", {{"session", created["session"]}, {"token", created["view_token"]}}) == -32003);
    expectNoEdits(x, -32009);
    CHECK(x.error("session.join", {{"session", created["session"]}, {"token", created["token"]}}) == -32003);
    expectNoEdits(x, -32009);
    CHECK(x.error("session.join", {{"session", created["session"]}, {"token", "wrong"}}) == -32002);
    CHECK(x.error("session.join", {{"session", "nosuchsession-000000001"}, {"token", created["token"]}}) == -32001);
    CHECK(x.error("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"protocol", 2}}) == -32008);
    expectNoEdits(x, -32009);
    CHECK(x.error("session.create", {{"size", {64, 64, 64}}, {"solid", "box"}, {"protocol", 2}}) == -32008);
    CHECK(x.error("session.create", {{"size", {64, 64, 256}}, {"solid", "box"}}) == -32004);
    CHECK(x.error("session.create", params) == -32014);
    expectNoEdits(x, -32009);
    TestClient other(hub);
    other.result("session.create", kCreate64);  // the second and last session
    CHECK(x.error("session.create", kCreate64) == -32004);
    expectNoEdits(x, -32009);
    CHECK(x.error("session.stats") == -32009);
  }
  SECTION("a view client stays a view client of its session") {
    CHECK(v.error("session.create", kCreate64) == -32010);
    CHECK(v.error("session.join", {{"session", created["session"]}, {"token", created["token"]}}) == -32010);
    expectNoEdits(v, -32007);
    CHECK(v.result("session.stats")["session"] == created["session"]);
  }
  SECTION("an editor keeps its rights and its session") {
    CHECK(a.error("session.join", {{"session", created["session"]}, {"token", created["view_token"]}}) == -32010);
    CHECK(a.error("session.create", kCreate64) == -32010);
    CHECK(a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 10, 32}}})["revision"] == 2);
    revision = 2;
  }
  // Nothing a refused connection sent changed the session; the full session still counts two.
  const json stats = a.result("session.stats");
  CHECK(stats["clients"].size() == 2);
  CHECK(stats["revision"] == revision);
  CHECK(stats["can_undo"] == true);
}

// A link like the network's: its sends may run inline on the caller's thread and, past its
// queue bound (here: the first -32005), disconnect the client from inside the send.
struct DisconnectingLink : CaptureLink {
  Hub* hub = nullptr;
  std::shared_ptr<HubClient> client;
  void sendText(std::string text) override {
    const bool busy = json::parse(text).value("error", json::object()).value("code", 0) == -32005;
    CaptureLink::sendText(std::move(text));
    if (busy && client) hub->disconnect(client);
  }
};

TEST_CASE("a reader that floods and falls behind is disconnected without deadlocking the sender", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxPendingMessages = 4;
  Hub hub(o);
  auto link = std::make_shared<DisconnectingLink>();
  link->hub = &hub;
  link->client = hub.connect(link, "flooder");
  // Before the fix the refusal was sent under the client's lock and the inline disconnect took it
  // again: this thread hung. A hang cannot be failed cleanly, so the flood runs on its own thread.
  auto done = std::make_shared<std::promise<void>>();
  std::future<void> flooded = done->get_future();
  std::thread([&hub, client = link->client, done] {
    for (int i = 0; i < 200; ++i)
      hub.text(client, json{{"jsonrpc", "2.0"}, {"id", i}, {"method", "session.create"}, {"params", kCreate64}}.dump());
    done->set_value();
  }).detach();
  if (flooded.wait_for(kWait) != std::future_status::ready) {
    std::fprintf(stderr, "deadlock: Hub::text never returned after an inline disconnect\n");
    std::_Exit(1);
  }
  link->waitFor([](const auto& m) {
    const json* j = std::get_if<json>(&m);
    return j && j->contains("error") && (*j)["error"]["code"] == -32005;
  });
  hub.disconnect(link->client);
  link->client.reset();
}

TEST_CASE("ids and secrets the server makes never begin with '-', so command lines take them as values", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxCreatesPerMinute = 1000;
  o.limits.maxCreatesPerAddressPerMinute = 1000;
  Hub hub(o);
  TestClient a(hub);
  // 3 × 150 draws: with a uniform first character over all 64, one of them begins with '-' with
  // probability 1 - (63/64)^450 > 0.999.
  std::set<char> first;
  for (int i = 0; i < 150; ++i) {
    const json r = a.result("session.create", {{"size", {8, 8, 8}}, {"solid", "empty"}});
    for (const char* key : {"session", "token", "view_token"}) {
      const std::string text = r[key].get<std::string>();
      REQUIRE(!text.empty());
      CHECK(std::isalnum(static_cast<unsigned char>(text[0])));
      first.insert(text[0]);
    }
    a.result("session.leave", json::object());
  }
  CHECK(first.size() > 40);  // still spread over the alphanumerics
}

TEST_CASE("one connection cannot take every session slot", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxSessions = 2;
  o.limits.maxCreatesPerMinute = 3;
  o.limits.maxCreatesPerAddressPerMinute = 5;
  Hub hub(o);
  const auto waitForSessions = [&](std::size_t n) {
    const auto deadline = std::chrono::steady_clock::now() + kWait;
    while (hub.sessionCount() != n && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    return hub.sessionCount();
  };
  TestClient a(hub), b(hub), other(hub);
  // The issue's reproduction: create and leave again and again. A session left unchanged goes
  // at once, so the slots stay free; the rate bounds stop the loop.
  for (int i = 0; i < 3; ++i) {
    a.result("session.create", kCreate64);
    a.result("session.leave");
    CHECK(waitForSessions(0) == 0);
  }
  const json perConnection = a.call("session.create", kCreate64);
  CHECK(perConnection["error"]["code"] == -32004);
  CHECK(perConnection["error"]["data"]["limit"] == "max_creates_per_minute");
  b.result("session.create", kCreate64);
  b.result("session.leave");
  // A changed session stays for the idle timeout.
  const json kept = b.result("session.create", kCreate64);
  b.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  b.result("session.leave");
  CHECK(waitForSessions(1) == 1);
  // Both connections come from one address ("test"): five creates in the minute are all it gets.
  const json perAddress = other.call("session.create", kCreate64);
  CHECK(perAddress["error"]["code"] == -32004);
  CHECK(perAddress["error"]["data"]["limit"] == "max_creates_per_address_per_minute");
  CHECK(other.result("session.join", {{"session", kept["session"]}, {"token", kept["token"]}})["revision"] == 1);
}

TEST_CASE("outputs are sized from the band before they are built", "[hub]") {
  // The estimate: a mesh file's size from the crossed edges, against the real file.
  json created;
  std::size_t stlBytes = 0, objBytes = 0, plyBytes = 0;
  {
    Hub hub(smallOptions());
    TestClient a(hub);
    created = a.result("session.create", {{"size", {96, 96, 96}}, {"solid", "pig"}, {"view", "none"}});
    stlBytes = a.result("mesh.export", {{"format", "stl"}})["bytes"];
    objBytes = a.result("mesh.export", {{"format", "obj"}})["bytes"];
    plyBytes = a.result("mesh.export", {{"format", "ply"}})["bytes"];
  }
  HubOptions o = smallOptions();
  o.limits.maxOutputBytes = 1;
  o.limits.maxVolumeBytes = 64 << 10;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", {{"size", {96, 96, 96}}, {"solid", "pig"}, {"view", "none"}});
  const std::size_t mark = a.link->size();
  for (const auto& [format, real] : {std::pair<std::string, std::size_t>{"stl", stlBytes}, {"obj", objBytes}, {"ply", plyBytes}}) {
    const json refused = a.call("mesh.export", {{"format", format}});
    INFO(format << ": " << refused.dump() << " real " << real);
    CHECK(refused["error"]["code"] == -32004);
    CHECK(refused["error"]["data"]["limit"] == "max_output_bytes");
    const double ratio = refused["error"]["data"]["value"].get<double>() / double(real);
    CHECK(ratio > 0.8);
    CHECK(ratio < 1.3);
  }
  const json splats = a.call("splats.get");
  CHECK(splats["error"]["data"]["limit"] == "max_output_bytes");
  // Nothing was built and sent.
  for (std::size_t i = mark; i < a.link->size(); ++i) CHECK(std::holds_alternative<json>(a.link->at(i)));
  // A volume over max_volume_bytes is refused before it replaces the session's.
  const std::vector<std::uint8_t> file = saveVolume(makeSolid(SolidKind::Pig, {96, 96, 96}));
  const int id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", file.size()}}}}.dump());
  a.hub.binary(a.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
  const json loaded = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
  CHECK(loaded["error"]["data"]["limit"] == "max_volume_bytes");
  CHECK(a.result("session.stats")["revision"] == 0);
}

// A painted session's mesh files carry vertex colours (marching_cubes.hpp): the estimate counts
// their bytes too.
TEST_CASE("a painted session's mesh files are sized with their colours", "[hub][color]") {
  Volume painted = makeSolid(SolidKind::Pig, {96, 96, 96});
  test::paintBricks(painted, [](Int3 b, int i) {
    const Int3 p = Bricks::origin(b) + Bricks::local(i);
    return Texel{std::uint8_t(2 * p.x), std::uint8_t(2 * p.y), std::uint8_t(2 * p.z), 0};
  });
  const std::vector<std::uint8_t> file = saveVolume(painted);
  auto load = [&](TestClient& c) {
    const int id = c.nextId++;
    c.hub.text(c.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", file.size()}}}}.dump());
    c.hub.binary(c.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
    const json loaded = std::get<json>(c.link->at(c.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
    REQUIRE(loaded.contains("result"));
  };
  std::map<std::string, std::size_t> real;
  {
    Hub hub(smallOptions());
    TestClient a(hub);
    a.result("session.create", {{"size", {96, 96, 96}}, {"solid", "pig"}, {"view", "none"}});
    load(a);
    for (const char* format : {"obj", "ply", "glb"}) real[format] = a.result("mesh.export", {{"format", format}})["bytes"];
  }
  HubOptions o = smallOptions();
  o.limits.maxOutputBytes = 1;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", {{"size", {96, 96, 96}}, {"solid", "pig"}, {"view", "none"}});
  load(a);
  for (const auto& [format, bytes] : real) {
    const json refused = a.call("mesh.export", {{"format", format}});
    REQUIRE(refused["error"]["data"]["limit"] == "max_output_bytes");
    const double ratio = refused["error"]["data"]["value"].get<double>() / double(bytes);
    INFO(format << ": estimate " << refused["error"]["data"]["value"] << ", file " << bytes << ", ratio " << ratio);
    CHECK(ratio > 0.9);
    CHECK(ratio < 1.1);
  }
}

TEST_CASE("the requester gets its response, then the notification, then the delta", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  a.link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsFull); });
  const std::size_t mark = a.link->size();
  const int id = a.nextId;
  a.result("tool.apply", {{"tool", "remove_blob"}, {"center", {32, 54, 32}}});
  const std::size_t delta = a.link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsDelta); }, mark);
  const std::size_t response = a.link->waitFor([&](const auto& m) { return isResponse(m, id); }, mark);
  const std::size_t note = a.link->waitFor([](const auto& m) { return isNotification(m, "session.changed"); }, mark);
  CHECK(response < note);
  CHECK(note < delta);
}

TEST_CASE("an edit reaches its session's strand from the thread that takes it, never through the workers' queue",
          "[hub]") {
  // Under load every task in the workers' queue waits behind each busy session's turn: a hop
  // there before the strand doubled a message's wait. HubEvents::request runs in the dispatch,
  // on the thread that hands the request to its handler. One worker, so that its queue is one
  // line: a task posted there runs only after the one it is running now has returned. No timing
  // decides what is checked: the order of that line, and GateLink's holds, do.
  std::mutex mutex;
  std::vector<std::thread::id> dispatched;
  HubOptions o = smallOptions();
  o.workers = 1;
  o.events.request = [&](std::string_view) {
    const std::lock_guard lock(mutex);
    dispatched.push_back(std::this_thread::get_id());
  };
  const auto count = [&] {
    const std::lock_guard lock(mutex);
    return dispatched.size();
  };
  const auto dispatcherOf = [&](std::size_t k) {
    const std::lock_guard lock(mutex);
    REQUIRE(k < dispatched.size());
    return dispatched[k];
  };
  Hub hub(o);
  const auto answer = [&](GateLink& link, int id) {
    const json r = std::get<json>(link.at(link.waitFor([&](const auto& m) { return isResponse(m, id); })));
    INFO(r.dump());
    CHECK(r.contains("result"));
  };
  // a edits its session; b, in another, puts its strand's task in the worker's queue.
  json create = kCreate64;
  create["view"] = "none";
  const auto aLink = std::make_shared<GateLink>(), bLink = std::make_shared<GateLink>();
  const OpenOnExit open{{aLink, bLink}};
  const auto a = hub.connect(aLink, "a"), b = hub.connect(bLink, "b");
  sendRequest(hub, a, 1, "session.create", create);
  answer(*aLink, 1);
  sendRequest(hub, b, 1, "session.create", create);
  answer(*bLink, 1);
  const json blob = {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 3}};

  // On an idle connection: by the thread that hands the message over (the network's). The
  // worker lets a's connection go just after sending its answer, in the same task: b's edit,
  // posted to the worker's queue once that answer is here, is answered after a's connection is
  // idle again.
  for (int round = 0; round < 5; ++round) {
    sendRequest(hub, b, 10 + round, "tool.apply", blob);
    answer(*bLink, 10 + round);
    const std::size_t k = count();
    sendRequest(hub, a, 10 + round, "tool.apply", blob);
    answer(*aLink, 10 + round);
    INFO("round " << round);
    CHECK(dispatcherOf(k) == std::this_thread::get_id());
  }

  // Queued behind an edit: by the worker that answered that edit, right after answering, before
  // it takes the next task of its queue. a's first edit is held at its answer (in its strand
  // task, see GateLink) while a's second is queued behind it and b's edit is posted to the
  // worker's queue with its own answer held; when b's answer is reached, a's second must have
  // been dispatched, by the worker that answered a's first.
  for (int round = 0; round < 5; ++round) {
    const int first = 100 + 2 * round, second = first + 1, other = 100 + round;
    aLink->gateAt(first);
    bLink->gateAt(other);
    sendRequest(hub, a, first, "tool.apply", blob);
    aLink->waitUntil(aLink->atResult);
    sendRequest(hub, a, second, "tool.apply", blob);
    const std::size_t k = count();
    sendRequest(hub, b, other, "tool.apply", blob);
    REQUIRE(count() == k + 1);  // b's edit, dispatched by this thread on its idle connection
    aLink->set(aLink->resultOpen);
    bLink->waitUntil(bLink->atResult);
    const std::size_t dispatchedBeforeB = count();
    bLink->set(bLink->resultOpen);
    const std::size_t answered = aLink->waitFor([&](const auto& m) { return isResponse(m, first); });
    answer(*aLink, second);
    answer(*bLink, other);
    std::thread::id answerer;
    {
      const std::lock_guard lock(aLink->mutex);
      answerer = aLink->senders[answered];
    }
    INFO("round " << round);
    REQUIRE(dispatchedBeforeB == k + 2);
    CHECK(dispatcherOf(k + 1) == answerer);
    CHECK(answerer != std::this_thread::get_id());
  }
  hub.disconnect(a);
  hub.disconnect(b);
}

TEST_CASE("a client's stream of stroke.begin does not hold back another client's edit", "[hub]") {
  // Every message takes its turn on the session's strand behind those already waiting there,
  // whatever its method: a client sending stroke.begin after stroke.begin without waiting for the
  // answers (each ends the stroke before it, a journal record each) gets one turn before another
  // client's edit waiting behind its first, not all of them. No timing decides it: b's own
  // stroke.begin holds the strand (its answer is held, see GateLink) while a's first begin and
  // b's edit are handed over; the order is read from the answers as the strand sent them.
  Hub hub(smallOptions());
  TestClient a0(hub);
  const json created = a0.result("session.create", kCreate64);
  const auto order = std::make_shared<SendOrder>();
  const auto joined = [&](const std::string& peer) {
    auto link = std::make_shared<GateLink>();
    link->order = order;
    const auto client = hub.connect(link, peer);
    hub.text(client, json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "session.join"},
                          {"params", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}}}}
                         .dump());
    link->waitFor([](const auto& m) { return isResponse(m, 1); });
    return std::pair{link, client};
  };
  const auto [aLink, a] = joined("a");
  const auto [bLink, b] = joined("b");
  const OpenOnExit open{{aLink, bLink}};
  const json begin = {{"tool", "add_blob"}, {"radius", 4}, {"strength", 0.5}};
  constexpr int kBegins = 30;
  for (int round = 0; round < 5; ++round) {
    const int first = 1000 + 100 * round, hold = 10 + 2 * round, edit = hold + 1;
    bLink->gateAt(hold);
    sendRequest(hub, b, hold, "stroke.begin", begin);
    bLink->waitUntil(bLink->atResult);
    {
      const std::lock_guard lock(order->mutex);
      order->sent.clear();
    }
    for (int i = 0; i < kBegins; ++i) sendRequest(hub, a, first + i, "stroke.begin", begin);
    sendRequest(hub, b, edit, "tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 6}});
    bLink->set(bLink->resultOpen);
    const std::size_t answered = bLink->waitFor([&](const auto& m) { return isResponse(m, edit); });
    CHECK(std::get<json>(bLink->at(answered)).contains("result"));
    aLink->waitFor([&](const auto& m) { return isResponse(m, first + kBegins - 1); });
    const std::lock_guard lock(order->mutex);
    std::vector<std::pair<const void*, json>> answers;
    for (const auto& s : order->sent)
      if (s.second != hold) answers.push_back(s);
    REQUIRE(answers.size() == kBegins + 1);
    INFO("round " << round);
    CHECK(answers[0] == std::pair<const void*, json>(aLink.get(), first));
    CHECK(answers[1] == std::pair<const void*, json>(bLink.get(), edit));
    for (int i = 1; i < kBegins; ++i) CHECK(answers[std::size_t(i + 1)] == std::pair<const void*, json>(aLink.get(), first + i));
  }
  hub.disconnect(a);
  hub.disconnect(b);
}

TEST_CASE("undo and redo restore exact digests, splat deltas add up to a fresh full buffer", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  const std::string d0 = a.result("session.stats")["digest"];
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 6}});
  const json stroke = a.result("stroke.begin", {{"tool", "remove_blob"}, {"radius", 5}, {"symmetry", {"x"}}});
  const json dabs = a.result("stroke.dabs", {{"stroke", stroke["stroke"]},
                                             {"dabs", {{{"center", {20, 40, 32}}},
                                                       {{"ray", {{"origin", {32, 32, 200}}, {"direction", {0, 0, -1}}}}, {"pressure", 0.5}},
                                                       {{"ray", {{"origin", {32, 200, 200}}, {"direction", {0, 0, 1}}}}}}}});
  CHECK(dabs["applied"] == 2);  // the last ray points away from the solid
  CHECK(dabs["revision"] == 2);
  CHECK(a.error("stroke.dabs", {{"stroke", 999}, {"dabs", {{{"center", {1, 1, 1}}}}}}) == -32011);
  const json ended = a.result("stroke.end", {{"stroke", stroke["stroke"]}});
  CHECK(ended["can_undo"] == true);
  const std::string d2 = a.result("session.stats")["digest"];
  a.result("volume.morph", {{"kind", "dilate"}, {"radius", 1}});
  const std::string d3 = a.result("session.stats")["digest"];

  // One undo step per apply, stroke and morph.
  CHECK(a.result("history.undo")["revision"] == 4);
  CHECK(a.result("session.stats")["digest"] == d2);
  a.result("history.undo");
  a.result("history.undo");
  const json last = a.call("history.undo");
  CHECK(last["error"]["code"] == -32012);
  CHECK(a.result("session.stats")["digest"] == d0);
  a.result("history.redo");
  a.result("history.redo");
  const json redone = a.result("history.redo");
  CHECK(redone["can_redo"] == false);
  CHECK(a.result("session.stats")["digest"] == d3);

  // A delta leaves out a brick whose points its clients were sent already: no brick comes
  // again with the points (or none) an earlier delta gave it (bricksAroundChanges lists many
  // such, whose voxels changed away from the surface).
  Held held, listed;
  std::size_t deltas = 0, bricks = 0;
  for (std::size_t i = 0; i < a.link->size(); ++i) {
    const auto m = a.link->at(i);
    const Bytes* b = std::get_if<Bytes>(&m);
    if (!b) continue;
    applySplats(held, *b);
    if (headerOf(*b).kind != protocol::FrameKind::SplatsDelta) continue;
    ++deltas;
    for (auto& [brick, points] : blocksOf(*b)) {
      INFO("delta " << deltas << " brick " << brick[0] << " " << brick[1] << " " << brick[2]);
      const auto before = listed.find(brick);
      CHECK((before == listed.end() || before->second != points));
      listed[brick] = std::move(points);
      ++bricks;
    }
  }
  CHECK(deltas == 9);  // apply, dabs, morph, three undos, three redos
  CHECK(bricks > 0);
  Held fresh;
  const int id = a.nextId;
  a.result("splats.get");
  const std::size_t f = a.link->waitFor([&](const auto& m) {
    return std::holds_alternative<Bytes>(m) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
  });
  applySplats(fresh, std::get<Bytes>(a.link->at(f)));
  CHECK(held.size() == fresh.size());
  CHECK(held == fresh);
}

TEST_CASE("after a splats-mode client's splats.get the next delta sends every brick it lists again", "[hub]") {
  // splats.get's full buffer may reach its client after deltas sent meanwhile and replace what
  // they brought: the session's record of what its clients hold starts afresh once the buffer
  // is queued. Two twin sessions make the same two edits; in one, splats.get comes between. The
  // edits are paint strokes: the engine lists every brick whose paint changed, which includes
  // stored bricks just inside the surface with no splat (their voxels' foot points lie under the
  // brush), whose empty block the record holds after the first stroke and drops from the second
  // delta, unless it started afresh.
  Hub hub(smallOptions());
  TestClient x(hub), y(hub);
  std::vector<std::uint32_t> listed;
  const auto paint = [](TestClient& t, const json& color) {
    const std::size_t mark = t.link->size();
    const json begun = t.result("stroke.begin", {{"tool", "paint"}, {"color", color}, {"radius", 8}});
    t.result("stroke.dabs", {{"stroke", begun["stroke"]}, {"dabs", {{{"center", {32, 60, 32}}}}}});
    const std::size_t d = t.link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsDelta); }, mark);
    t.result("stroke.end", {{"stroke", begun["stroke"]}});
    return std::uint32_t(blocksOf(std::get<Bytes>(t.link->at(d))).size());
  };
  for (TestClient* t : {&x, &y}) {
    t->result("session.create", kCreate64);
    paint(*t, {200, 20, 10});
    if (t == &y) {
      const int id = y.nextId;
      y.result("splats.get");
      y.link->waitFor([&](const auto& m) {
        return std::holds_alternative<Bytes>(m) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
      });
      y.result("session.stats");  // behind the strand task that starts the record afresh
    }
    listed.push_back(paint(*t, {10, 200, 30}));
  }
  INFO("bricks in the second delta: " << listed[0] << " without splats.get, " << listed[1] << " after it");
  CHECK(listed[0] < listed[1]);
}


TEST_CASE("edits while a splats-mode client's splats.get buffer is on its way leave it with the session's splats",
          "[hub]") {
  // y's buffer is a snapshot taken before edit A; A's delta reaches y first, then the buffer
  // takes A's bricks back to before A, then B (the same blob again) lists them: B's delta must
  // send them whatever the session's record says y was sent (one sent before the buffer landed
  // held 4 wrong bricks here).
  Hub hub(smallOptions());
  TestClient x(hub);
  const json created = x.result("session.create", kCreate64);
  auto link = std::make_shared<GateLink>();
  const auto y = hub.connect(link, "y");
  const OpenOnExit open{{link}};  // a failed wait must not leave y's worker held at shutdown
  hub.text(y, json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "session.join"},
                   {"params", {{"session", created["session"]}, {"token", created["token"]}}}}
                  .dump());
  link->waitFor([](const auto& m) { return isFrame(m, protocol::FrameKind::SplatsFull); });
  link->gate = 2;
  hub.text(y, json{{"jsonrpc", "2.0"}, {"id", 2}, {"method", "splats.get"}, {"params", json::object()}}.dump());
  link->waitUntil(link->atFrame);
  const json blob = {{"tool", "add_blob"}, {"center", {32, 54, 32}}, {"radius", 6}};
  const auto edit = [&] {  // until y has its delta
    const std::uint64_t revision = x.result("tool.apply", blob)["revision"];
    link->waitFor([&](const auto& m) {
      return isFrame(m, protocol::FrameKind::SplatsDelta) && headerOf(std::get<Bytes>(m)).revision == revision;
    });
  };
  edit();  // A
  link->set(link->frameOpen);
  link->waitUntil(link->atResult);  // the buffer is queued, the call not over
  edit();  // B
  link->set(link->resultOpen);
  link->waitFor([](const auto& m) { return isResponse(m, 2); });
  x.result("session.stats");
  Held held;
  const std::size_t mark = link->size();
  for (std::size_t i = 0; i < mark; ++i)
    if (const auto m = link->at(i); const Bytes* b = std::get_if<Bytes>(&m)) applySplats(held, *b);
  link->gate = -1;
  hub.text(y, json{{"jsonrpc", "2.0"}, {"id", 3}, {"method", "splats.get"}, {"params", json::object()}}.dump());
  const std::size_t f = link->waitFor([](const auto& m) {
    return std::holds_alternative<Bytes>(m) && headerOf(std::get<Bytes>(m)).requestId == 3;
  }, mark);
  Held fresh;
  applySplats(fresh, std::get<Bytes>(link->at(f)));
  // B's bricks, from a twin of the session. A brick only A listed stays as the older buffer
  // left it: deltas that reach a client before a buffer of an earlier revision are undone by it
  // (PROTOCOL.md, splats.get), with or without the record; not counted.
  Session twin(makeSolid(SolidKind::Sphere, {64, 64, 64}));
  const protocol::Op op = protocol::parseToolApplyParams(blob).op;
  twin.apply(op, ThreadPool::serial());
  std::size_t listed = 0, wrong = 0;
  for (const Int3 b : twin.apply(op, ThreadPool::serial()).bricks) {
    const std::array<int, 3> brick{b.x, b.y, b.z};
    ++listed;
    wrong += held.count(brick) != fresh.count(brick) || (held.count(brick) && held.at(brick) != fresh.at(brick));
  }
  CHECK(listed > 10);
  CHECK(wrong == 0);
  hub.disconnect(y);
}

TEST_CASE("tool.apply with a ray reports the hit, or changes nothing when it misses", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  const json hit = a.result("tool.apply", {{"tool", "add_blob"}, {"ray", {{"origin", {31.5, 31.5, 200}}, {"direction", {0, 0, -2}}}}});
  // The sphere of radius 22.4 around (31.5, 31.5, 31.5): the ray meets it at z = 53.9.
  CHECK(hit["hit"][2].get<double>() == Approx(53.9).margin(0.1));
  CHECK(hit["revision"] == 1);
  const json miss = a.result("tool.apply", {{"tool", "add_blob"}, {"ray", {{"origin", {0, 200, 200}}, {"direction", {0, 1, 0}}}}});
  CHECK(miss["hit"].is_null());
  CHECK(miss["roi"].is_null());
  CHECK(miss["revision"] == 1);
  CHECK(a.call("tool.apply", {{"tool", "add_blob"}, {"center", {1, 2, 3}}, {"ray", {{"origin", {0, 0, 0}}, {"direction", {0, 0, 1}}}}})
            ["error"]["data"]["field"] == "center");
  CHECK(a.call("tool.apply", {{"tool", "add_blob"}, {"ray", {{"origin", {0, 0, 0}}, {"direction", {0, 0, 0}}}}})["error"]["data"]["field"] ==
        "ray");
  CHECK(a.call("tool.apply", {{"op", "morph"}, {"kind", "erode"}, {"radius", 1}})["error"]["data"]["field"] == "op");
  CHECK(a.error("tool.apply", {{"tool", "add_blob"}, {"center", {500, 500, 500}}}) == -32006);
  CHECK(a.call("tool.apply", {{"tool", "add_blob"}, {"center", {1, 2, 3}}, {"strength", 0}})["error"]["data"]["field"] == "strength");
  CHECK(a.call("tool.apply", {{"tool", "warp"}, {"center", {1, 2, 3}}})["error"]["data"]["field"] == "tool");
  CHECK(a.result("session.stats")["revision"] == 1);
}

TEST_CASE("stroke.dabs refuses more than max_dabs and zero pressure", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxDabs = 3;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreate64);
  const json s = a.result("stroke.begin", {{"tool", "smooth"}});
  json four = json::array();
  for (int i = 0; i < 4; ++i) four.push_back({{"center", {32, 54, 32}}});
  const json over = a.call("stroke.dabs", {{"stroke", s["stroke"]}, {"dabs", four}});
  CHECK(over["error"]["code"] == -32004);
  CHECK(over["error"]["data"]["limit"] == "max_dabs");
  CHECK(a.call("stroke.dabs", {{"stroke", s["stroke"]}, {"dabs", {{{"center", {32, 54, 32}}, {"pressure", 0}}}}})["error"]["code"] ==
        -32602);
  CHECK(a.error("stroke.begin", {{"tool", "smooth"}, {"accumulate", "yes"}}) == -32602);
  CHECK(a.result("stroke.begin", {{"tool", "smooth"}, {"accumulate", true}})["stroke"] == 2);
  CHECK(a.result("session.stats")["revision"] == 0);
}

TEST_CASE("a stroke with a height rises by it however often it passes, its rays picked as the stroke began",
          "[hub][stroke]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);  // a sphere of radius 22.4 about 31.5
  for (const json& bad : {json{{"tool", "smooth"}, {"height", 1}}, json{{"tool", "sharpen"}, {"height", 1}},
                          json{{"tool", "add_blob"}, {"accumulate", true}, {"height", 1}},
                          json{{"tool", "add_blob"}, {"radius", 8}, {"height", 4.01}},
                          json{{"tool", "remove_blob"}, {"height", -1}}, json{{"tool", "add_blob"}, {"height", "3"}}}) {
    INFO(bad.dump());
    const json e = a.call("stroke.begin", bad)["error"];
    CHECK(e["code"] == -32602);
    CHECK(e["data"]["field"] == "height");
  }
  const double before = a.result("session.stats")["inside_volume"];
  // Rays straight down onto the top of the sphere, along x.
  json rays = json::array();
  for (double x = 24; x <= 39; x += 1.5) rays.push_back({{"ray", {{"origin", {x, 100, 31.5}}, {"direction", {0, -1, 0}}}}});
  const auto stroke = [&](int passes) {
    const json s = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 8}, {"height", 3}});
    for (int p = 0; p < passes; ++p) a.result("stroke.dabs", {{"stroke", s["stroke"]}, {"dabs", rays}});
    a.result("stroke.end", {{"stroke", s["stroke"]}});
    const json stats = a.result("session.stats");
    a.result("history.undo");
    return stats;
  };
  const json once = stroke(1), thrice = stroke(3);
  const double added = once["inside_volume"].get<double>() - before;
  const double top = once["bounds"]["hi"][1].get<double>() - (31.5 + 22.4);
  INFO("one pass adds " << added << " vu^3 and raises the top " << top << " vu; three passes add "
                        << thrice["inside_volume"].get<double>() - before);
  CHECK(top == Approx(3).margin(0.5));  // bounds are a voxel box
  CHECK(std::fabs(thrice["inside_volume"].get<double>() - before - added) <= 0.005 * added);
  CHECK(a.result("session.stats")["inside_volume"] == before);
}

TEST_CASE("render.frame sends an image of the requested size before its response", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  const json camera = {{"eye", {32, 40, 150}}, {"target", {32, 32, 32}}};
  for (const char* format : {"png", "jpeg"}) {
    const int id = a.nextId;
    const json r = a.result("render.frame", {{"camera", camera}, {"width", 96}, {"height", 64}, {"format", format}});
    CHECK(r["width"] == 96);
    const std::size_t response = a.link->waitFor([&](const auto& m) { return isResponse(m, id); });
    const std::size_t frame = a.link->waitFor([&](const auto& m) {
      return std::holds_alternative<Bytes>(m) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
    });
    CHECK(frame < response);
    const Bytes f = std::get<Bytes>(a.link->at(frame));
    CHECK(headerOf(f).kind == (std::string(format) == "png" ? protocol::FrameKind::FramePng : protocol::FrameKind::FrameJpeg));
    CHECK(f.size() - protocol::kFrameHeaderBytes == r["bytes"].get<std::size_t>());
    CHECK(imageSize(payloadOf(f)) == std::pair<int, int>{96, 64});
  }
  CHECK(a.call("render.frame", {{"camera", camera}, {"width", 5000}, {"height", 64}, {"format", "png"}})["error"]["code"] == -32004);
  CHECK(a.call("render.frame", {{"camera", {{"eye", {1, 1, 1}}, {"target", {1, 1, 1}}}}, {"width", 8}, {"height", 8}, {"format", "png"}})
            ["error"]["code"] == -32006);
  CHECK(a.call("render.frame", {{"camera", camera}, {"width", 8}, {"height", 8}, {"format", "png"}, {"quality", 50}})["error"]["data"]
            ["field"] == "quality");
}

TEST_CASE("frames mode pushes a frame at once and after every change, then a still one", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
  const json r = a.result("view.set", {{"mode", "frames"}, {"camera", {{"eye", {32, 40, 150}}, {"target", {32, 32, 32}}}}, {"width", 80}, {"height", 60}});
  CHECK(r["mode"] == "frames");
  const auto pushedJpeg = [](const auto& m) {
    return isFrame(m, protocol::FrameKind::FrameJpeg) && headerOf(std::get<Bytes>(m)).requestId == 0;
  };
  const std::size_t first = a.link->waitFor(pushedJpeg);
  CHECK(imageSize(payloadOf(std::get<Bytes>(a.link->at(first)))) == std::pair<int, int>{80, 60});
  // The still frame follows the interactive one when nothing changes.
  a.link->waitFor(pushedJpeg, first + 1);
  const std::size_t mark = a.link->size();
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  const std::size_t after = a.link->waitFor(pushedJpeg, mark);
  CHECK(headerOf(std::get<Bytes>(a.link->at(after))).revision == 1);
  CHECK(a.call("view.set", {{"mode", "none"}, {"shading", "normals"}})["error"]["data"]["field"] == "shading");
  CHECK(a.result("view.set", {{"mode", "frames"}, {"camera", {{"eye", {32, 40, 150}}, {"target", {32, 32, 32}}}}, {"width", 8},
                              {"height", 8}, {"shading", "gradient_error"}})["mode"] == "frames");
  // No splat buffers in frames mode.
  for (std::size_t i = mark; i < a.link->size(); ++i)
    CHECK_FALSE(isFrame(a.link->at(i), protocol::FrameKind::SplatsDelta));
}

TEST_CASE("mesh.export and volume.save send files, volume.load takes one back as one undo step", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", kCreate64);
  int id = a.nextId;
  const json stl = a.result("mesh.export", {{"format", "stl"}});
  Bytes file = std::get<Bytes>(a.link->at(a.link->waitFor([&](const auto& m) {
    return isFrame(m, protocol::FrameKind::MeshStl) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
  })));
  CHECK(file.size() - protocol::kFrameHeaderBytes == 84 + 50 * stl["triangles"].get<std::size_t>());
  CHECK(stl["triangles"].get<int>() > 1000);
  CHECK(a.call("mesh.export", {{"format", "fbx"}})["error"]["data"]["field"] == "format");
  CHECK(a.call("mesh.export", {{"format", "glb"}, {"max_triangles", 0}})["error"]["data"]["field"] == "max_triangles");
  CHECK(a.call("mesh.export", {{"format", "glb"}, {"max_error", -1}})["error"]["data"]["field"] == "max_error");

  // glTF, decimated to a budget: the result reports what was reached and how far it strays.
  id = a.nextId;
  const json glb = a.result("mesh.export", {{"format", "glb"}, {"max_triangles", 500}});
  file = std::get<Bytes>(a.link->at(a.link->waitFor([&](const auto& m) {
    return isFrame(m, protocol::FrameKind::MeshGlb) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
  })));
  CHECK(std::string(file.begin() + protocol::kFrameHeaderBytes, file.begin() + protocol::kFrameHeaderBytes + 4) == "glTF");
  CHECK(glb["source_triangles"] == stl["triangles"]);
  CHECK(glb["triangles"].get<int>() <= 500);
  CHECK(glb["triangles"].get<int>() > 400);
  CHECK(glb["max_error"].get<double>() > 0);
  CHECK(glb["max_error"].get<double>() < 3);
  CHECK_FALSE(stl.contains("max_error"));

  id = a.nextId;
  const json saved = a.result("volume.save");
  const Bytes mzv = std::get<Bytes>(a.link->at(a.link->waitFor([&](const auto& m) {
    return isFrame(m, protocol::FrameKind::VolumeFile) && headerOf(std::get<Bytes>(m)).requestId == std::uint32_t(id);
  })));
  const std::vector<std::uint8_t> payload(mzv.begin() + protocol::kFrameHeaderBytes, mzv.end());
  CHECK(payload.size() == saved["bytes"].get<std::size_t>());

  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  CHECK(a.result("session.stats")["digest"] != saved["digest"]);
  const auto upload = [&](std::uint32_t requestId, std::span<const std::uint8_t> bytes) {
    a.hub.binary(a.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, requestId, 0, bytes));
  };
  id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", payload.size()}}}}.dump());
  upload(std::uint32_t(id), payload);
  const json loaded = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
  INFO(loaded.dump());
  CHECK(loaded["result"]["digest"] == saved["digest"]);
  CHECK(loaded["result"]["can_undo"] == true);
  a.result("history.undo");
  CHECK(a.result("session.stats")["digest"] != saved["digest"]);

  // An upload of another length, and a load not followed by its upload, fail with -32013.
  id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", payload.size() + 4}}}}.dump());
  upload(std::uint32_t(id), payload);
  CHECK(std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })))["error"]["code"] == -32013);
  id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", payload.size()}}}}.dump());
  CHECK(a.result("session.stats")["revision"] == 3);
  CHECK(std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })))["error"]["code"] == -32013);

  // A truncated file and a file of another grid are refused by the engine; nothing changes.
  const std::string before = a.result("session.stats")["digest"];
  const std::vector<std::uint8_t> truncated(payload.begin(), payload.end() - 9);
  id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", truncated.size()}}}}.dump());
  upload(std::uint32_t(id), truncated);
  const json bad = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
  CHECK(bad["error"]["code"] == -32006);
  const std::vector<std::uint8_t> other = saveVolume(makeSolid(SolidKind::Box, {32, 32, 32}));
  id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", other.size()}}}}.dump());
  upload(std::uint32_t(id), other);
  const json wrongGrid = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
  CHECK(wrongGrid["error"]["code"] == -32006);
  CHECK(wrongGrid["error"]["data"]["field"] == "file");
  CHECK(a.result("session.stats")["digest"] == before);
}

TEST_CASE("limits: sessions, clients per session, and requests in flight", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxSessions = 1;
  o.limits.maxClientsPerSession = 1;
  o.limits.maxPendingMessages = 2;
  Hub hub(o);
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", {{"size", {128, 128, 128}}, {"solid", "sphere"}});
  const json full = b.call("session.create", kCreate64);
  CHECK(full["error"]["code"] == -32004);
  CHECK(full["error"]["data"]["limit"] == "max_sessions");
  const json crowded = b.call("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  CHECK(crowded["error"]["code"] == -32003);

  // A long global operation holds the connection; what arrives beyond the bound is refused.
  for (int i = 0; i < 6; ++i) {
    const json params = i == 0 ? json{{"tool", "smooth"}, {"global", true}, {"iterations", 8}} : json::object();
    a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", 100 + i}, {"method", i == 0 ? "tool.apply" : "session.stats"}, {"params", params}}.dump());
  }
  int busy = 0;
  for (int i = 0; i < 6; ++i) {
    const json r = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, 100 + i); })));
    if (r.contains("error")) {
      CHECK(r["error"]["code"] == -32005);
      ++busy;
    }
  }
  CHECK(busy >= 3);
}

TEST_CASE("a connection that floods requests is throttled, another one is not", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxRequestsPerSecond = 5;
  Hub hub(o);
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate64);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  const std::size_t mark = a.link->size();
  for (int i = 0; i < 30; ++i)
    a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", 500 + i}, {"method", "session.stats"}}.dump());
  int busy = 0, answered = 0;
  for (int i = 0; i < 30; ++i) {
    const json r = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, 500 + i); }, mark)));
    if (r.contains("error")) {
      CHECK(r["error"]["code"] == -32005);
      ++busy;
    } else {
      ++answered;
    }
  }
  // A burst of two seconds' worth (10, one of them spent on session.create) passes, the rest
  // is refused at once.
  CHECK(answered >= 9);
  CHECK(answered <= 12);
  CHECK(busy == 30 - answered);
  CHECK(b.result("session.stats")["revision"] == 0);
}

TEST_CASE("a text of max_text_bytes refused over the rate limit is answered Busy with the id it names", "[hub]") {
  HubOptions o = smallOptions();
  o.limits.maxRequestsPerSecond = 1;
  Hub hub(o);
  TestClient a(hub);
  // 1 MiB of params holding "id" keys (and one in a string); the request's id comes after them.
  std::string params = R"({"pad":[)";
  while (params.size() < (std::size_t(1) << 20)) params += R"([{"id":-1,"s":"\"id\":-2"},[1.5,null]],)";
  params += "0]}";
  const auto big = [&](const std::string& id) {
    return R"({"jsonrpc":"2.0","method":"session.stats","params":)" + params + (id.empty() ? "" : R"(,"id":)" + id) + "}";
  };
  const std::size_t mark = a.link->size();
  for (int i = 0; i < 6; ++i) a.hub.text(a.client, big(std::to_string(900 + i)));
  a.hub.text(a.client, big("\"over\""));
  a.hub.text(a.client, big(""));         // a notification: never answered
  a.hub.text(a.client, big("7") + "}");  // not JSON: its id cannot be known
  a.hub.text(a.client, big("1.5"));      // an id that is not one: cannot be echoed
  a.hub.text(a.client, big("\"end\""));
  const auto responseTo = [&](const json& id) {
    return std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); }, mark)));
  };
  // The burst (two seconds' worth) is parsed and refused (no session); the rest is Busy.
  int busy = 0;
  for (int i = 0; i < 6; ++i) {
    const json r = responseTo(900 + i);
    REQUIRE(r.contains("error"));
    busy += r["error"]["code"] == -32005;
  }
  CHECK(busy >= 4);
  for (const json& id : {json("over"), json("end")}) {
    const json r = responseTo(id);
    CHECK(r["error"]["code"] == -32005);
    CHECK(r["error"]["data"]["retry_after_ms"] == 100);
  }
  std::vector<json> nulls;
  for (std::size_t i = mark; i < a.link->size(); ++i) {
    const std::variant<json, Bytes> m = a.link->at(i);
    if (const json* j = std::get_if<json>(&m); j && j->contains("id") && (*j)["id"].is_null()) nulls.push_back(*j);
  }
  REQUIRE(nulls.size() == 2);
  for (const json& r : nulls) CHECK(r["error"]["code"] == -32005);
}

TEST_CASE("an idle session is saved to the data directory, unloaded, and loaded on join", "[hub]") {
  const auto dir = std::filesystem::temp_directory_path() / "marzipan-hub-idle";
  std::filesystem::remove_all(dir);
  HubOptions o = smallOptions();
  o.dataDir = dir;
  o.limits.idleSession = std::chrono::seconds(1);
  json created;
  std::string digest;
  {
    Hub hub(o);
    TestClient a(hub);
    created = a.result("session.create", kCreate64);
    a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
    digest = a.result("session.stats")["digest"];
    a.result("session.leave");
    const auto deadline = std::chrono::steady_clock::now() + kWait;
    while (hub.sessionCount() > 0 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    CHECK(hub.sessionCount() == 0);
    CHECK(std::filesystem::exists(dir / "sessions" / created["session"].get<std::string>() / "snapshot-1.mzv"));
    TestClient b(hub);
    CHECK(b.error("session.join", {{"session", created["session"]}, {"token", "nope"}}) == -32002);
    const json joined = b.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}});
    CHECK(joined["digest"] == digest);
    CHECK(joined["revision"] == 1);
    CHECK(joined["read_only"] == true);
  }
  // A second hub on the same directory (another server, or a restart) serves it too.
  Hub again(o);
  TestClient c(again);
  CHECK(c.result("session.join", {{"session", created["session"]}, {"token", created["token"]}})["digest"] == digest);
  TestClient d(again);
  CHECK(d.error("session.create", json{{"size", {64, 64, 64}}, {"solid", "box"}, {"session", created["session"]}}) == -32014);
  std::filesystem::remove_all(dir);
}

TEST_CASE("uploads kept in the data directory do not pile up", "[hub]") {
  const auto dir = std::filesystem::temp_directory_path() / "marzipan-hub-loads";
  std::filesystem::remove_all(dir);
  HubOptions o = smallOptions();
  o.dataDir = dir;
  Hub hub(o);
  TestClient a(hub);
  const json created = a.result("session.create", kCreate64);
  const std::vector<std::uint8_t> file = saveVolume(makeSolid(SolidKind::Box, {64, 64, 64}));
  for (int i = 0; i < 4; ++i) {
    const int id = a.nextId++;
    a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", "volume.load"}, {"params", {{"bytes", file.size()}}}}.dump());
    a.hub.binary(a.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
    CHECK(std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })))["result"]["revision"] == i + 1);
  }
  CHECK(a.result("history.undo")["revision"] == 5);
  std::size_t loads = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "sessions" / created["session"].get<std::string>()))
    if (e.path().filename().string().rfind("load-", 0) == 0) ++loads;
  CHECK(loads <= 1);
  std::filesystem::remove_all(dir);
}

TEST_CASE("sessions at rest untouched for max_session_age are deleted", "[hub]") {
  const auto dir = std::filesystem::temp_directory_path() / "marzipan-hub-age";
  std::filesystem::remove_all(dir);
  HubOptions o = smallOptions();
  o.dataDir = dir;
  json old, young;
  {
    Hub hub(o);
    TestClient a(hub), b(hub);
    old = a.result("session.create", kCreate64);
    young = b.result("session.create", kCreate64);
  }
  // Both are at rest now; one looks 91 days old.
  const auto past = std::filesystem::file_time_type::clock::now() - std::chrono::hours(24 * 91);
  for (const auto& e : std::filesystem::directory_iterator(dir / "sessions" / old["session"].get<std::string>()))
    std::filesystem::last_write_time(e.path(), past);
  Hub hub(o);
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (std::filesystem::exists(dir / "sessions" / old["session"].get<std::string>()) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  TestClient c(hub);
  CHECK(c.error("session.join", {{"session", old["session"]}, {"token", old["token"]}}) == -32001);
  CHECK(c.result("session.join", {{"session", young["session"]}, {"token", young["token"]}})["revision"] == 0);
  CHECK(c.result("session.stats")["clients"].size() == 1);
  std::filesystem::remove_all(dir);
}

TEST_CASE("leaving and disconnecting update the others' client lists", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  const json created = a.result("session.create", kCreate64);
  {
    TestClient b(hub);
    b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
    a.link->waitFor([](const auto& m) {
      return isNotification(m, "session.clients") && std::get<json>(m)["params"]["clients"].size() == 2;
    });
  }
  a.link->waitFor([](const auto& m) {
    return isNotification(m, "session.clients") && std::get<json>(m)["params"]["clients"].size() == 1;
  });
  CHECK(a.result("session.leave")["session"] == created["session"]);
  CHECK(a.error("session.stats") == -32009);
}

TEST_CASE("analysis.thickness finds the thinnest places, frames shade thickness", "[hub]") {
  Hub hub(smallOptions());
  TestClient a(hub);
  a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}});
  // The sphere's radius is 0.35 * 64 = 22.4: every chord through the centre is 44.8 vu.
  const json all = a.result("analysis.thickness", {{"min_vu", 50}, {"max_places", 5}});
  CHECK(all["points"].get<int>() > 1000);
  CHECK(all["below"] == all["points"]);
  CHECK(all["thinnest"].get<double>() == Approx(44.8).margin(0.2));
  REQUIRE(all["places"].size() == 5);
  CHECK(all["places"][0]["thickness"] == all["thinnest"]);
  const json none = a.result("analysis.thickness", {{"min_vu", 40}});
  CHECK(none["below"] == 0);
  CHECK(none["places"].empty());
  CHECK(a.call("analysis.thickness", {{"max_places", 3}})["error"]["data"]["field"] == "min_vu");
  CHECK(a.call("analysis.thickness", {{"min_vu", 0}})["error"]["data"]["field"] == "min_vu");
  CHECK(a.call("analysis.thickness", {{"min_vu", 1}, {"max_places", 0}})["error"]["data"]["field"] == "max_places");

  const json camera = {{"eye", {32, 32, 150}}, {"target", {32, 32, 32}}};
  CHECK(a.result("render.frame", {{"camera", camera}, {"width", 16}, {"height", 16}, {"format", "png"},
                                  {"shading", "thickness"}, {"min_vu", 50}})["format"] == "png");
  CHECK(a.call("render.frame", {{"camera", camera}, {"width", 16}, {"height", 16}, {"format", "png"}, {"min_vu", 5}})
            ["error"]["data"]["field"] == "min_vu");
  CHECK(a.result("view.set", {{"mode", "frames"}, {"camera", camera}, {"width", 16}, {"height", 16},
                              {"shading", "thickness"}, {"min_vu", 3}})["mode"] == "frames");
}
