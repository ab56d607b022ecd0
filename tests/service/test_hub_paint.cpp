// Paint and mask through the hub (methods_edit.cpp, methods_session.cpp; PROTOCOL.md, paint and
// mask strokes, mask.clear/invert/fill): stroke.begin/dabs/end of paint and mask with symmetry
// and the stroke memory, one step each in history.list, undo and redo back to the digests, the
// mask methods as steps refused for view clients, base_color in session.create/join/fork,
// presence relaying the paint colour, a journal cut by snapshots mid-stroke that recovers the
// live digest, and hostile params refused with their field, changing nothing.
#include <catch2/catch.hpp>

#include <filesystem>
#include <string>
#include <vector>

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

namespace {

const json kCreate = {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"view", "none"}};
// The 64^3 sphere's surface points on +x and -x (centre 31.5, radius 22.4).
const json kSide = {53.9, 31.5, 31.5};
const json kOtherSide = {9.1, 31.5, 31.5};

std::string fieldOf(const json& e) { return e["data"]["field"]; }

// One stroke of `begin` over the dabs, one message each; returns the last revision.
std::uint64_t stroke(TestClient& c, const json& begin, const std::vector<json>& centres) {
  const std::uint64_t id = c.result("stroke.begin", begin)["stroke"];
  std::uint64_t revision = 0;
  for (const json& p : centres) revision = c.result("stroke.dabs", {{"stroke", id}, {"dabs", {{{"center", p}}}}})["revision"];
  c.result("stroke.end", {{"stroke", id}});
  return revision;
}

std::vector<std::string> stepTools(TestClient& c) {
  std::vector<std::string> out;
  const json listed = c.result("history.list");
  for (const json& st : listed["steps"]) out.push_back(st["tool"]);
  return out;
}

}  // namespace

TEST_CASE("hub paint: paint and mask strokes are steps that undo and redo to their digests", "[hub][paint]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  CHECK(created["base_color"] == json{221, 181, 155});
  const std::string start = a.digest();
  const json paint = {{"tool", "paint"}, {"color", {200, 20, 10}}, {"radius", 6}, {"symmetry", {"x"}}};
  CHECK(stroke(a, paint, {kSide, {53.9, 34.5, 31.5}}) == 2);
  const std::string painted = a.digest();
  CHECK(painted != start);
  // The same dabs again: remembered, nothing changes (revision 2 stays).
  const std::uint64_t again = a.result("stroke.begin", paint)["stroke"];
  CHECK(a.result("stroke.dabs", {{"stroke", again}, {"dabs", {{{"center", kSide}}}}})["revision"] == 3);
  CHECK(a.result("stroke.dabs", {{"stroke", again}, {"dabs", {{{"center", kSide}}}}})["applied"] == 0);
  a.result("stroke.end", {{"stroke", again}});
  a.result("history.undo");
  CHECK(a.digest() == painted);
  stroke(a, {{"tool", "mask"}, {"radius", 8}}, {kOtherSide});
  const std::string masked = a.digest();
  stroke(a, {{"tool", "mask"}, {"radius", 8}, {"erase", true}}, {kOtherSide});
  // Erased where it was added: lower again (gone in the brush's core, where alpha is 1).
  CHECK(a.digest() != masked);
  CHECK(stepTools(a) == std::vector<std::string>{"mask", "mask", "paint"});  // newest first
  a.result("history.undo");
  CHECK(a.digest() == masked);
  a.result("history.undo");
  a.result("history.undo");
  CHECK(a.digest() == start);
  a.result("history.redo");
  CHECK(a.digest() == painted);
}

TEST_CASE("hub paint: mask.fill, mask.invert and mask.clear are steps, view clients are refused", "[hub][paint][mask]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), v(hub);
  const json created = a.result("session.create", kCreate);
  const std::string start = a.digest();
  const json joined = v.result("session.join", {{"session", created["session"]}, {"token", created["view_token"]}, {"view", "none"}});
  CHECK(joined["base_color"] == json{221, 181, 155});
  for (const std::string m : {"mask.fill", "mask.invert", "mask.clear"}) {
    const json e = v.errorObject(m);
    CHECK(e["code"] == -32007);
  }
  CHECK(a.digest() == start);
  const json filled = a.result("mask.fill");
  CHECK(filled["revision"] == 1);
  CHECK(filled["roi"]["lo"] == json{0, 0, 0});
  const std::string full = a.digest();
  CHECK(full != start);
  CHECK(a.result("mask.invert")["revision"] == 2);
  CHECK(a.digest() == start);  // all 255 inverted: all 0, no channels
  a.result("mask.fill");
  a.result("mask.clear");
  CHECK(a.digest() == start);
  // Nothing left to clear: no change, no step.
  const json none = a.result("mask.clear");
  CHECK(none["revision"] == 4);
  CHECK(none["roi"].is_null());
  CHECK(stepTools(a) == std::vector<std::string>{"mask.clear", "mask.fill", "mask.invert", "mask.fill"});  // newest first
  CHECK(a.errorObject("mask.fill", {{"weight", 255}})["code"] == -32602);
  a.result("history.undo");
  CHECK(a.digest() == full);
}

TEST_CASE("hub paint: a fully masked session keeps its bits under add_blob, smooth and csg_add", "[hub][paint][mask]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub);
  a.result("session.create", kCreate);
  stroke(a, {{"tool", "paint"}, {"color", {10, 200, 30}}, {"radius", 8}}, {kSide});
  a.result("mask.fill");
  const std::string frozen = a.digest();
  const std::uint64_t revision = a.result("session.stats")["revision"];
  CHECK(stroke(a, {{"tool", "add_blob"}, {"radius", 8}}, {kSide, {53.9, 34.5, 31.5}}) == revision);
  CHECK(stroke(a, {{"tool", "smooth"}, {"radius", 8}}, {kSide}) == revision);
  const json csg = a.result("tool.apply", {{"tool", "csg_add"}, {"shape", "sphere"}, {"center", {50.9, 31.5, 31.5}}, {"radius", 2}});
  CHECK(csg["revision"] == revision);
  CHECK(csg["roi"].is_null());
  CHECK(a.digest() == frozen);
}

TEST_CASE("hub paint: base_color makes the session's clay, join and fork carry it", "[hub][paint]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub), c(hub);
  json create = kCreate;
  create["base_color"] = {120, 130, 150};
  create["splats"] = 2;
  const json created = a.result("session.create", create);
  CHECK(created["base_color"] == json{120, 130, 150});
  c.result("session.create", kCreate);
  // The same sphere in another clay: another digest.
  CHECK(a.digest() != c.digest());
  const json joined = b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"splats", 2}, {"view", "none"}});
  CHECK(joined["base_color"] == json{120, 130, 150});
  stroke(b, {{"tool", "paint"}, {"color", {1, 2, 3}}, {"radius", 5}}, {kSide});
  const std::string live = b.digest();
  const json forked = b.result("session.fork");
  CHECK(forked["base_color"] == json{120, 130, 150});
  CHECK(forked["digest"] == live);
}

TEST_CASE("hub paint: presence relays the paint tool and its colour", "[hub][paint][presence]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}, {"view", "none"}});
  const std::size_t mark = b.link->size();
  const json brush = {{"tool", "paint"}, {"radius", 6}, {"point", kSide}, {"normal", {1, 0, 0}}, {"active", true},
                      {"color", {250, 5, 80}}};
  a.result("presence", {{"brush", brush}});
  const std::size_t at = b.link->waitFor(
      [](const auto& m) { return isNotification(m, "presence") && std::get<json>(m)["params"].contains("brush"); }, mark);
  const json got = std::get<json>(b.link->at(at))["params"]["brush"];
  CHECK(got["tool"] == "paint");
  CHECK(got["color"] == json{250, 5, 80});
  CHECK(a.errorObject("presence", {{"brush", {{"tool", "paint"}, {"radius", 6}, {"point", kSide}, {"normal", {1, 0, 0}},
                                           {"active", true}, {"color", {256, 0, 0}}}}})["code"] == -32602);
}

TEST_CASE("hub paint: the journal, cut by snapshots inside paint strokes, recovers the live digest", "[hub][paint]") {
  const fs::path dir = fs::temp_directory_path() / "marzipan-hub-paint-journal";
  const fs::path crashed = fs::temp_directory_path() / "marzipan-hub-paint-journal-crashed";
  fs::remove_all(dir);
  fs::remove_all(crashed);
  HubOptions o = twoWorkerOptions(dir);
  o.snapshotEvery = 3;
  std::string id, live;
  {
    Hub hub(o);
    TestClient a(hub);
    json create = kCreate;
    create["base_color"] = {90, 160, 200};
    id = a.result("session.create", create)["session"];
    stroke(a, {{"tool", "paint"}, {"color", {200, 20, 10}}, {"radius", 6}, {"symmetry", {"y"}}},
           {kSide, {53.9, 33.5, 31.5}, {53.9, 35.5, 31.5}, {53.9, 37.5, 30.5}});
    a.result("mask.fill");
    a.result("history.undo");  // a step file with channels
    a.result("history.redo");
    stroke(a, {{"tool", "mask"}, {"radius", 6}, {"erase", true}, {"accumulate", true}}, {kSide, kSide});
    a.result("mask.invert");
    a.result("tool.apply", {{"tool", "csg_add"}, {"shape", "box"}, {"center", {31.5, 53.9, 31.5}}, {"radius", 4}, {"color", {0, 255, 0}}});
    // A paint stroke left open over the last snapshots: recovery ends it where it was, its memory
    // cut by the snapshot and announced again at the head of the new journal.
    const std::uint64_t open = a.result("stroke.begin", {{"tool", "paint"}, {"color", {0, 0, 255}}, {"radius", 5}})["stroke"];
    for (const json& p : {kOtherSide, json{9.1, 33.5, 31.5}, json{9.1, 35.5, 31.5}, json{9.1, 33.5, 31.5}})
      a.result("stroke.dabs", {{"stroke", open}, {"dabs", {{{"center", p}}}}});
    live = a.digest();
    fs::copy(dir, crashed, fs::copy_options::recursive);
  }
  SessionStore store(crashed);
  const Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  CHECK(r.session->stats().measures.digest == live);
  CHECK(r.session->digest() == r.session->stats().digest);
  fs::remove_all(dir);
  fs::remove_all(crashed);
}

TEST_CASE("hub paint: hostile params are refused with their field and change nothing", "[hub][paint][errors]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub);
  a.result("session.create", kCreate);
  const std::string start = a.digest();
  const auto refused = [&](const json& begin, const std::string& field) {
    const json e = a.errorObject("stroke.begin", begin);
    CHECK(e["code"] == -32602);
    CHECK(fieldOf(e) == field);
  };
  refused({{"tool", "paint"}}, "color");
  refused({{"tool", "paint"}, {"color", {1, 2}}}, "color");
  refused({{"tool", "paint"}, {"color", {1, 2, 300}}}, "color");
  refused({{"tool", "paint"}, {"color", {1, 2, -3}}}, "color");
  refused({{"tool", "paint"}, {"color", {1, 2.5, 3}}}, "color");
  refused({{"tool", "paint"}, {"color", "#ff0000"}}, "color");
  refused({{"tool", "paint"}, {"color", {1, 2, 3}}, {"height", 2}}, "height");
  refused({{"tool", "paint"}, {"color", {1, 2, 3}}, {"radius", 1e12}}, "radius");
  refused({{"tool", "mask"}, {"hardness", 1}}, "hardness");
  refused({{"tool", "mask"}, {"erase", "yes"}}, "erase");
  // NaN cannot be written in JSON: a text that holds it is not JSON.
  const json nan = a.rawResponse(R"({"jsonrpc":"2.0","id":99,"method":"stroke.begin","params":{"tool":"paint","color":[1,2,3],"strength":NaN}})", nullptr);
  CHECK(nan["error"]["code"] == -32700);
  json e = a.errorObject("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}, {"base_color", {0, 0}}});
  CHECK(e["code"] == -32602);
  CHECK(fieldOf(e) == "base_color");
  e = a.errorObject("tool.apply", {{"op", "mask"}, {"action", "fill"}});
  CHECK(e["code"] == -32602);
  e = a.errorObject("mask.invert", {{"action", "invert"}});
  CHECK(fieldOf(e) == "action");
  // A paint stroke's dab off the domain: refused, named, nothing changes.
  const std::uint64_t s = a.result("stroke.begin", {{"tool", "paint"}, {"color", {1, 2, 3}}, {"radius", 4}})["stroke"];
  e = a.errorObject("stroke.dabs", {{"stroke", s}, {"dabs", {{{"center", kSide}}, {{"center", {900, 0, 0}}}}}});
  CHECK(e["code"] == -32006);
  CHECK(fieldOf(e) == "dabs[1].center");
  CHECK(a.digest() == start);
  CHECK(a.result("history.list")["steps"].empty());
}
