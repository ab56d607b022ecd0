// service/hub/methods_edit.cpp: the stroke.dabs messages of one stroke queued behind the one
// being handled on a connection are applied with it as one application (one revision, one
// journal record, one delta), each still answered in order; never for an accumulating stroke,
// another stroke, another connection, past max_dabs, or when the application is refused.
//
// How the tests queue messages: a client's messages are handled one at a time, so a volume.morph
// that takes a while keeps the dabs sent right after it waiting in the connection's queue; when
// the first of them runs, the others are already there. The answers are compared with a second
// session that receives the same dabs as one message (bit for bit) or as separate messages
// (within the stroke's semantics: the same volume within 5%).
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/measures.hpp"
#include "engine/thread_pool.hpp"
#include "protocol/cpp/frames.hpp"
#include "service/hub.hpp"
#include "service/session_store.hpp"
#include "hub_support.hpp"
#include "storage_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// A sphere of radius ~44.8 about 63.5: the morph below keeps the connection busy for a while.
const json kCreate = {{"size", {128, 128, 128}}, {"solid", "sphere"}};
const json kMorph = {{"kind", "dilate"}, {"radius", 2}};

// Rays straight down onto the top of the sphere at x = x0, x0 + 2, ...; origin x = 500 misses.
json rays(std::vector<double> xs) {
  json out = json::array();
  for (double x : xs) out.push_back({{"ray", {{"origin", {x, 200, 63.5}}, {"direction", {0, -1, 0}}}}});
  return out;
}
const std::vector<json> kMessages = {rays({56, 58, 60}), rays({62, 64}), rays({66, 500, 68})};

json allDabs() {
  json all = json::array();
  for (const json& m : kMessages)
    for (const json& d : m) all.push_back(d);
  return all;
}

void send(TestClient& c, int id, const std::string& method, const json& params) {
  c.hub.text(c.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump());
}

json responseTo(TestClient& c, int id) {
  return std::get<json>(c.link->at(c.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
}

// A volume.morph (or another request that takes a while), then each of `messages` as
// stroke.dabs of `stroke`, sent at once: the dabs wait behind it on the connection. Returns its
// response, then the dabs'.
std::vector<json> queueBehindMorph(TestClient& c, const json& stroke, const std::vector<json>& messages,
                                   const std::string& method = "volume.morph", const json& params = kMorph) {
  const int first = c.nextId;
  c.nextId += int(messages.size()) + 1;
  send(c, first, method, params);
  for (std::size_t i = 0; i < messages.size(); ++i)
    send(c, first + 1 + int(i), "stroke.dabs", {{"stroke", stroke}, {"dabs", messages[i]}});
  std::vector<json> out;
  for (int id = first; id <= first + int(messages.size()); ++id) out.push_back(responseTo(c, id));
  return out;
}

std::size_t countOf(CaptureLink& link, std::size_t from,
                    const std::function<bool(const std::variant<json, Bytes>&)>& pred) {
  std::size_t n = 0;
  for (std::size_t i = from; i < link.size(); ++i) n += pred(link.at(i)) ? 1 : 0;
  return n;
}

bool isDelta(const std::variant<json, Bytes>& m) {
  const Bytes* b = std::get_if<Bytes>(&m);
  if (!b) return false;
  const auto d = protocol::decodeFrameHeader(*b);
  return d && d.frame->header.kind == protocol::FrameKind::SplatsDelta;
}

// The digest of the session `id` as the data directory alone recovers it.
std::string recoveredDigest(const fs::path& dir, const std::string& id) {
  return digestHex(recoverCopy(dir, id)->volume());
}

}  // namespace

TEST_CASE("queued stroke.dabs of one stroke are one application, each answered, journaled and undone exactly",
          "[hub][stroke]") {
  const fs::path dir = freshDir("one");
  Hub hub(twoWorkerOptions(dir));
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  const json stroke = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}, {"height", 2}})["stroke"];
  a.link->waitFor([](const auto& m) { return std::holds_alternative<Bytes>(m); });
  const std::size_t mark = a.link->size();
  const std::vector<json> r = queueBehindMorph(a, stroke, kMessages);
  REQUIRE(r.size() == 4);
  for (const json& x : r) REQUIRE(x.contains("result"));
  const std::uint64_t morphed = r[0]["result"]["revision"];
  // One application: one revision for the three, each message its own count of applied dabs.
  for (int i = 1; i <= 3; ++i) {
    CHECK(r[std::size_t(i)]["result"]["revision"] == morphed + 1);
    CHECK(r[std::size_t(i)]["result"]["roi"] == r[1]["result"]["roi"]);
  }
  CHECK(r[1]["result"]["applied"] == 3);
  CHECK(r[2]["result"]["applied"] == 2);
  CHECK(r[3]["result"]["applied"] == 2);  // the ray from x = 500 misses
  // Answered in request order; one session.changed and one delta for the stroke's application.
  std::vector<std::size_t> at;
  for (const json& x : r) at.push_back(a.link->waitFor([&](const auto& m) { return isResponse(m, x["id"]); }, mark));
  CHECK(std::is_sorted(at.begin(), at.end()));
  const json stats = a.result("session.stats");
  CHECK(stats["revision"] == morphed + 1);
  CHECK(countOf(*a.link, mark, [](const auto& m) { return isNotification(m, "session.changed"); }) == 2);
  CHECK(countOf(*a.link, mark, isDelta) == 2);

  // Bit for bit what one message with all the dabs makes.
  Hub other(twoWorkerOptions());
  TestClient b(other);
  b.result("session.create", kCreate);
  const json s1 = b.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}, {"height", 2}})["stroke"];
  b.result("volume.morph", kMorph);
  const std::string before = b.result("session.stats")["digest"];
  const double inside = b.result("session.stats")["inside_volume"];
  const json one = b.result("stroke.dabs", {{"stroke", s1}, {"dabs", allDabs()}});
  CHECK(one["applied"] == 7);
  CHECK(b.result("session.stats")["digest"] == stats["digest"]);
  CHECK(stats["digest"] != before);
  // Within the stroke's semantics what the messages make one by one: the same volume added.
  b.result("stroke.end", {{"stroke", s1}});
  b.result("history.undo");
  CHECK(b.result("session.stats")["digest"] == before);
  const json s2 = b.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}, {"height", 2}})["stroke"];
  for (const json& m : kMessages) b.result("stroke.dabs", {{"stroke", s2}, {"dabs", m}});
  const double apart = b.result("session.stats")["inside_volume"].get<double>() - inside;
  const double merged = stats["inside_volume"].get<double>() - inside;
  INFO("added " << merged << " vu^3 as one application, " << apart << " as three");
  CHECK(merged > 0);
  CHECK(std::fabs(merged - apart) <= 0.05 * apart);

  // The journal holds the one application: recovery reaches the same digest.
  CHECK(recoveredDigest(dir, created["session"]) == stats["digest"]);
  // The stroke is one undo step, undone and redone exactly.
  a.result("stroke.end", {{"stroke", stroke}});
  a.result("history.undo");
  CHECK(a.result("session.stats")["digest"] == before);
  a.result("history.redo");
  CHECK(a.result("session.stats")["digest"] == stats["digest"]);
  CHECK(recoveredDigest(dir, created["session"]) == stats["digest"]);
  fs::remove_all(dir);
}

TEST_CASE("an accumulating stroke's queued messages are applied one by one", "[hub][stroke]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub);
  a.result("session.create", kCreate);
  const json stroke = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}, {"accumulate", true}})["stroke"];
  const std::vector<json> r = queueBehindMorph(a, stroke, kMessages);
  const std::uint64_t morphed = r[0]["result"]["revision"];
  for (std::size_t i = 1; i <= 3; ++i) CHECK(r[i]["result"]["revision"] == morphed + i);
}

TEST_CASE("a stroke's messages merge only up to max_dabs, and never across another request or stroke",
          "[hub][stroke]") {
  HubOptions o = twoWorkerOptions();
  o.limits.maxDabs = 5;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreate);
  const json stroke = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}})["stroke"];
  SECTION("max_dabs") {
    // 3 + 2 dabs fit in one message's limit, 3 more would not: they are the next application.
    const std::vector<json> r = queueBehindMorph(a, stroke, {kMessages[0], kMessages[1], kMessages[2], kMessages[1]});
    const std::uint64_t morphed = r[0]["result"]["revision"];
    CHECK(r[1]["result"]["revision"] == morphed + 1);
    CHECK(r[2]["result"]["revision"] == morphed + 1);
    CHECK(r[3]["result"]["revision"] == morphed + 2);
    CHECK(r[4]["result"]["revision"] == morphed + 2);
  }
  SECTION("another method, a refused message, another stroke") {
    const int first = a.nextId;
    a.nextId += 7;
    send(a, first, "volume.morph", kMorph);
    send(a, first + 1, "stroke.dabs", {{"stroke", stroke}, {"dabs", kMessages[0]}});
    send(a, first + 2, "session.stats", json::object());
    send(a, first + 3, "stroke.dabs", {{"stroke", stroke}, {"dabs", kMessages[1]}});
    send(a, first + 4, "stroke.dabs", {{"stroke", 999}, {"dabs", kMessages[1]}});
    send(a, first + 5, "stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", {64, 64, 64}}, {"pressure", 2}}}}});
    send(a, first + 6, "stroke.dabs", {{"stroke", stroke}, {"dabs", kMessages[2]}});
    std::vector<json> r;
    for (int id = first; id < first + 7; ++id) r.push_back(responseTo(a, id));
    const std::uint64_t morphed = r[0]["result"]["revision"];
    CHECK(r[1]["result"]["revision"] == morphed + 1);
    CHECK(r[2]["result"]["revision"] == morphed + 1);
    CHECK(r[3]["result"]["revision"] == morphed + 2);
    CHECK(r[4]["error"]["code"] == -32011);
    CHECK(r[5]["error"]["code"] == -32602);
    CHECK(r[6]["result"]["revision"] == morphed + 3);
  }
  SECTION("a dab the engine refuses fails its own message only") {
    // The second message's dab lies outside the volume: the three are tried one by one.
    const json outside = {{{"center", {500, 500, 500}}}};
    const std::vector<json> r = queueBehindMorph(a, stroke, {kMessages[0], outside, kMessages[1]});
    const std::uint64_t morphed = r[0]["result"]["revision"];
    CHECK(r[1]["result"]["revision"] == morphed + 1);
    CHECK(r[2]["error"]["code"] == -32006);
    CHECK(r[3]["result"]["revision"] == morphed + 2);
  }
}

TEST_CASE("two clients' strokes are never one application", "[hub][stroke]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  const json sa = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 6}})["stroke"];
  const json sb = b.result("stroke.begin", {{"tool", "remove_blob"}, {"radius", 6}})["stroke"];
  // A's dabs wait behind its morph; B's go to the session meanwhile (its second behind its first).
  const int first = a.nextId;
  a.nextId += 3;
  send(a, first, "volume.morph", kMorph);
  send(a, first + 1, "stroke.dabs", {{"stroke", sa}, {"dabs", kMessages[0]}});
  send(a, first + 2, "stroke.dabs", {{"stroke", sa}, {"dabs", kMessages[1]}});
  const json onB = {rays({40, 42}), rays({44})};
  for (int i = 0; i < 2; ++i) send(b, 100 + i, "stroke.dabs", {{"stroke", sb}, {"dabs", onB[std::size_t(i)]}});
  const json a1 = responseTo(a, first + 1), a2 = responseTo(a, first + 2);
  const json b1 = responseTo(b, 100), b2 = responseTo(b, 101);
  for (const json& x : {a1, a2, b1, b2}) REQUIRE(x.contains("result"));
  CHECK(a1["result"]["revision"] == a2["result"]["revision"]);
  CHECK(a1["result"]["revision"] != b1["result"]["revision"]);
  CHECK(a1["result"]["revision"] != b2["result"]["revision"]);
  // Every change is one revision: the morph, A's application, B's one or two.
  const std::uint64_t revision = a.result("session.stats")["revision"];
  const std::uint64_t bChanges = b1["result"]["revision"] == b2["result"]["revision"] ? 1 : 2;
  CHECK(revision == 2 + bChanges);
}

TEST_CASE("a stroke's messages merge only while together they stay within max_op_voxels", "[hub][stroke]") {
  const json begin = {{"tool", "add_blob"}, {"radius", 6}, {"height", 2}};
  // What one dab of this stroke counts against the budget, as the refusal of one reports it.
  double perDab = 0;
  {
    HubOptions o = twoWorkerOptions();
    o.limits.maxOpVoxels = 1;
    Hub hub(o);
    TestClient a(hub);
    a.result("session.create", kCreate);
    const json stroke = a.result("stroke.begin", begin)["stroke"];
    const json e = a.call("stroke.dabs", {{"stroke", stroke}, {"dabs", rays({60})}})["error"];
    REQUIRE(e["data"]["limit"] == "max_op_voxels");
    perDab = e["data"]["value"];
  }
  REQUIRE(perDab > 0);
  HubOptions o = twoWorkerOptions();
  o.limits.maxOpVoxels = 5.5 * perDab;  // room for 5 dabs
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreate);
  const json stroke = a.result("stroke.begin", begin)["stroke"];
  // 3 + 2 dabs fit, 3 more would not: they start the next application, with the last 2. A
  // morph would be over this budget: the dabs wait behind a mesh export instead.
  const std::vector<json> r = queueBehindMorph(a, stroke, {kMessages[0], kMessages[1], kMessages[2], kMessages[1]},
                                               "mesh.export", {{"format", "obj"}});
  for (const json& x : r) REQUIRE(x.contains("result"));
  const std::uint64_t morphed = r[0]["result"]["revision"];
  CHECK(r[1]["result"]["revision"] == morphed + 1);
  CHECK(r[2]["result"]["revision"] == morphed + 1);
  CHECK(r[3]["result"]["revision"] == morphed + 2);
  CHECK(r[4]["result"]["revision"] == morphed + 2);
}
