// Warp strokes through the hub (methods_edit.cpp, PROTOCOL.md "Warp strokes"): the same volume
// for any grouping of a grab's messages, bit for bit; one undo step back to the start and the
// tool's name in history.list; a journal (cut by snapshots in the middle of strokes) that
// recovers to the live digest; refusals with their codes and fields that change nothing.
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
// The 64^3 sphere's surface point on +x (centre 31.5, radius 22.4).
const json kAnchor = {53.9, 31.5, 31.5};

json dab(double x, double y, double z) { return {{"center", {x, y, z}}}; }

// The pointer from the anchor to anchor + (dx, dy, dz) in n steps.
std::vector<json> dragDabs(double dx, double dy, double dz, int n) {
  std::vector<json> out;
  for (int i = 1; i <= n; ++i) {
    const double t = double(i) / n;
    out.push_back(dab(53.9 + dx * t, 31.5 + dy * t, 31.5 + dz * t));
  }
  return out;
}

}  // namespace

TEST_CASE("hub warp: a grab's volume does not depend on how its dabs are grouped into messages", "[hub][warp]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub);
  a.result("session.create", kCreate);
  b.result("session.create", kCreate);
  const std::string start = a.digest();
  const std::vector<json> pointer = dragDabs(7, 3, -2, 10);

  const std::uint64_t sa = a.result("stroke.begin", {{"tool", "grab"}, {"radius", 12}})["stroke"];
  json all = json::array({{{"center", kAnchor}}});
  for (const json& d : pointer) all.push_back(d);
  CHECK(a.result("stroke.dabs", {{"stroke", sa}, {"dabs", all}})["revision"] == 1);
  a.result("stroke.end", {{"stroke", sa}});

  const std::uint64_t sb = b.result("stroke.begin", {{"tool", "grab"}, {"radius", 12}})["stroke"];
  // The anchor alone changes nothing yet.
  CHECK(b.result("stroke.dabs", {{"stroke", sb}, {"dabs", {{{"center", kAnchor}}}}})["revision"] == 0);
  for (const json& d : pointer) b.result("stroke.dabs", {{"stroke", sb}, {"dabs", {d}}});
  b.result("stroke.end", {{"stroke", sb}});

  CHECK(a.digest() == b.digest());
  CHECK(a.digest() != start);
  // One step each, named grab; undo brings the start back.
  for (TestClient* c : {&a, &b}) {
    const json steps = c->result("history.list")["steps"];
    REQUIRE(steps.size() == 1);
    CHECK(steps[0]["tool"] == "grab");
    c->result("history.undo");
    CHECK(c->digest() == start);
  }
}

TEST_CASE("hub warp: the journal, cut by snapshots inside warp strokes, recovers the live digest", "[hub][warp]") {
  const fs::path dir = fs::temp_directory_path() / "marzipan-hub-warp-journal";
  const fs::path crashed = fs::temp_directory_path() / "marzipan-hub-warp-journal-crashed";
  fs::remove_all(dir);
  fs::remove_all(crashed);
  HubOptions o = twoWorkerOptions(dir);
  o.snapshotEvery = 3;
  std::string id, live;
  {
    Hub hub(o);
    TestClient a(hub);
    id = a.result("session.create", kCreate)["session"];
    for (const std::string tool : {"grab", "twist", "snake_hook", "elastic_grab", "pinch_path"}) {
      json begin = {{"tool", tool}, {"radius", 8}};
      if (tool == "twist") begin["direction"] = {0, 1, 0};
      const std::uint64_t s = a.result("stroke.begin", begin)["stroke"];
      a.result("stroke.dabs", {{"stroke", s}, {"dabs", {{{"center", kAnchor}}}}});
      for (const json& d : dragDabs(2, 5, 1, 6)) a.result("stroke.dabs", {{"stroke", s}, {"dabs", {d}}});
      a.result("stroke.end", {{"stroke", s}});
    }
    // A stroke left open over the last snapshots: recovery ends it where it was.
    const std::uint64_t open = a.result("stroke.begin", {{"tool", "scale"}, {"radius", 8}})["stroke"];
    a.result("stroke.dabs", {{"stroke", open}, {"dabs", {{{"center", {31.5, 53.9, 31.5}}}}}});
    for (const json& d : {dab(31.5, 55, 31.5), dab(31.5, 57, 31.5), dab(31.5, 56, 31.5), dab(31.5, 58, 31.5)})
      a.result("stroke.dabs", {{"stroke", open}, {"dabs", {d}}});
    live = a.digest();
    // The files as a crash would leave them (the hub saves a snapshot as it closes the session).
    fs::copy(dir, crashed, fs::copy_options::recursive);
  }
  SessionStore store(crashed);
  const Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  CHECK(r.session->stats().measures.digest == live);
  fs::remove_all(dir);
  fs::remove_all(crashed);
}

TEST_CASE("hub warp: refused requests name their field and change nothing", "[hub][warp]") {
  HubOptions o = twoWorkerOptions();
  o.limits.maxDabs = 16;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreate);
  const std::string start = a.digest();
  const auto field = [](const json& e) { return e["data"]["field"].get<std::string>(); };

  json e = a.errorObject("stroke.begin", {{"tool", "grab"}, {"symmetry", {"x"}}});
  CHECK(e["code"] == -32602);
  CHECK(field(e) == "symmetry");
  e = a.errorObject("stroke.begin", {{"tool", "snake_hook"}, {"accumulate", true}});
  CHECK(field(e) == "accumulate");
  e = a.errorObject("stroke.begin", {{"tool", "grab"}, {"radius", 500}});
  CHECK(e["code"] == -32602);
  CHECK(field(e) == "radius");
  e = a.errorObject("stroke.begin", {{"tool", "elastic_grab"}, {"radius", 30}});
  CHECK(field(e) == "radius");
  e = a.errorObject("stroke.begin", {{"tool", "grab"}, {"direction", {1, 0, 0}}});
  CHECK(field(e) == "direction");
  e = a.errorObject("stroke.begin", {{"tool", "twist"}, {"direction", {0, 0, 0}}});
  CHECK(field(e) == "direction");
  e = a.errorObject("tool.apply", {{"tool", "grab"}, {"center", kAnchor}});
  CHECK(e["code"] == -32602);
  // stroke.dabs before any stroke.begin.
  CHECK(a.error("stroke.dabs", {{"stroke", 1}, {"dabs", {{{"center", kAnchor}}}}}) == -32011);

  const std::uint64_t s = a.result("stroke.begin", {{"tool", "grab"}, {"radius", 10}})["stroke"];
  // An anchor 4 vu off the surface.
  e = a.errorObject("stroke.dabs", {{"stroke", s}, {"dabs", {dab(57.9, 31.5, 31.5), dab(60, 31.5, 31.5)}}});
  CHECK(e["code"] == -32602);
  CHECK(field(e) == "center");
  // JSON has no NaN (the session refuses one, test_session_warp.cpp); a centre that is no point.
  e = a.errorObject("stroke.dabs", {{"stroke", s}, {"dabs", {{{"center", {"x", 31.5, 31.5}}}}}});
  CHECK(e["code"] == -32602);
  CHECK(field(e) == "dabs");
  // Too many dabs in one message.
  json many = json::array();
  for (int i = 0; i < 17; ++i) many.push_back({{"center", kAnchor}});
  CHECK(a.error("stroke.dabs", {{"stroke", s}, {"dabs", many}}) == -32004);
  CHECK(a.digest() == start);
  CHECK(a.result("session.stats")["revision"] == 0);
  // The stroke still takes its anchor afterwards.
  CHECK(a.result("stroke.dabs", {{"stroke", s}, {"dabs", {{{"center", kAnchor}}, dab(56, 31.5, 31.5)}}})["revision"] == 1);
}

TEST_CASE("hub warp: a message over max_op_voxels is refused before any work", "[hub][warp]") {
  HubOptions o = twoWorkerOptions();
  o.limits.maxOpVoxels = 2e5;
  Hub hub(o);
  TestClient a(hub);
  a.result("session.create", kCreate);
  const std::string start = a.digest();
  const std::uint64_t s = a.result("stroke.begin", {{"tool", "grab"}, {"radius", 20}})["stroke"];
  // A short drag fits; a long one (its work grows with the drag) does not.
  CHECK(a.result("stroke.dabs", {{"stroke", s}, {"dabs", {{{"center", kAnchor}}, dab(54.9, 31.5, 31.5)}}})["revision"] == 1);
  const std::string after = a.digest();
  const json e = a.errorObject("stroke.dabs", {{"stroke", s}, {"dabs", {dab(53.9, 31.5 - 60, 31.5 + 60)}}});
  CHECK(e["code"] == -32004);
  CHECK(e["data"]["limit"] == "max_op_voxels");
  CHECK(a.digest() == after);
  CHECK(after != start);
}
