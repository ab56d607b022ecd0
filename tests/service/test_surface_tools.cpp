// The surface tools of issue 29 §2 (inflate, clay, flatten, contrast, crease) as the session and
// the hub drive them: strokes with symmetry, pressure and memory, the stroke's plane (fitted at
// its first dab on the starting volume, answered by stroke.dabs, journaled), journal replay to
// the same digest (also across a snapshot that cuts a stroke), undo as one step, history.list's
// tool names, tool.apply and refused input. The engine's own exactness (flatten's cap within
// 0.25 vu of a plane, crease's width) is tests/engine/level_set/test_tools.cpp's.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/apply_op.hpp"
#include "service/journal_records.hpp"
#include "service/session.hpp"
#include "service/session_store.hpp"
#include "hub_support.hpp"
#include "storage_support.hpp"
#include "session_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::requireError;
using namespace marzipan::service::testing;
using nlohmann::json;
using protocol::BrushTool;
namespace fs = std::filesystem;

namespace {

constexpr int kN = 48;
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;
const double kNaN = std::numeric_limits<double>::quiet_NaN();
const Vec3 kCentre{kC, kC, kC};

const Volume& sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

// A tool as a stroke takes it: name, tool, and a height for the tools that take one.
struct Case {
  const char* name;
  BrushTool tool;
  std::optional<double> height;
};
const std::vector<Case> kCases = {
    {"inflate", BrushTool::Inflate, std::nullopt}, {"inflate", BrushTool::Inflate, 2.0},
    {"clay", BrushTool::Clay, std::nullopt},       {"clay", BrushTool::Clay, 2.0},
    {"flatten", BrushTool::Flatten, std::nullopt}, {"contrast", BrushTool::Contrast, std::nullopt},
    {"crease", BrushTool::Crease, std::nullopt},
};

// On the sphere, off every mirror plane, the dabs of a short stroke across it.
Vec3 onSphere(Vec3 direction) { return kCentre + normalized(direction) * kR; }
std::vector<Dab> strokeDabs(double pressure = 1) {
  std::vector<Dab> out;
  for (double t : {0.0, 0.15, 0.3}) out.push_back(Dab{onSphere({1, 0.6 + t, 0.35}), pressure});
  return out;
}

double largestDifference(const Volume& a, const Volume& b) {
  double worst = 0;
  for (int z = 0; z < kN; ++z)
    for (int y = 0; y < kN; ++y)
      for (int x = 0; x < kN; ++x) worst = std::max(worst, double(std::fabs(a.at(x, y, z) - b.at(x, y, z))));
  return worst;
}

// The digest of the session `id` as the data directory alone recovers it.
std::string recoveredDigest(const fs::path& dir, const std::string& id) {
  return digestHex(recoverCopy(dir, id)->volume());
}

}  // namespace

TEST_CASE("surface tools: a stroke via the hub replays to its digest, undoes in one step and is listed by name",
          "[surface][hub]") {
  const fs::path dir = freshDir("hub");
  Hub hub(twoWorkerOptions(dir));
  TestClient a(hub);
  const json created = a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}});
  // Rays straight down onto the sphere's top (radius ~22.4 about 31.5), off the x = 31.5 plane.
  const auto rays = [](std::vector<double> xs) {
    json out = json::array();
    for (double x : xs) out.push_back({{"ray", {{"origin", {x, 100, 33}}, {"direction", {0, -1, 0}}}}});
    return out;
  };
  for (const Case& c : kCases) {
    const bool planar = brushUsesPlane(service::engineBrush(c.tool));
    DYNAMIC_SECTION(c.name << (c.height ? " with a height" : "")) {
      const std::string before = a.result("session.stats")["digest"];
      json begin{{"tool", c.name}, {"radius", 6}, {"strength", 0.8}, {"symmetry", {"x"}}};
      if (c.height) begin["height"] = *c.height;
      const json stroke = a.result("stroke.begin", begin)["stroke"];
      const json first = a.result("stroke.dabs", {{"stroke", stroke}, {"dabs", rays({36, 37.5})}});
      const json second = a.result("stroke.dabs", {{"stroke", stroke}, {"dabs", rays({39, 40.5})}});
      CHECK(first["applied"] == 2);
      CHECK(second["applied"] == 2);
      if (planar || (c.tool == BrushTool::Clay && c.height)) {
        // Fitted at the first dab on the sphere's top: a plane facing up through the cap, kept.
        REQUIRE(first.contains("plane"));
        const json& n = first["plane"]["normal"];
        CHECK(n[1].get<double>() > 0.9);
        CHECK(first["plane"]["point"][1].get<double>() < 31.5 + 22.4);
        CHECK(first["plane"]["point"][1].get<double>() > 31.5 + 22.4 - 2);
        CHECK(second["plane"] == first["plane"]);
      } else {
        CHECK_FALSE(first.contains("plane"));
      }
      a.result("stroke.end", {{"stroke", stroke}});
      const std::string after = a.result("session.stats")["digest"];
      CHECK(after != before);
      CHECK(recoveredDigest(dir, created["session"]) == after);
      const json listed = a.result("history.list", {{"limit", 1}});
      CHECK(listed["steps"][0]["tool"] == c.name);
      // One undo step for the stroke's two messages.
      a.result("history.undo");
      CHECK(a.result("session.stats")["digest"] == before);
      a.result("history.redo");
      CHECK(a.result("session.stats")["digest"] == after);
      CHECK(recoveredDigest(dir, created["session"]) == after);
    }
  }
  SECTION("tool.apply of each tool, flatten and contrast with the plane fitted at the centre, replays") {
    for (const char* tool : {"inflate", "clay", "flatten", "contrast", "crease"}) {
      INFO(tool);
      const std::string before = a.result("session.stats")["digest"];
      const json r = a.result("tool.apply", {{"tool", tool}, {"radius", 5}, {"ray", {{"origin", {38, 100, 30}},
                                                                                       {"direction", {0, -1, 0}}}}});
      CHECK(a.result("session.stats")["digest"] != before);
      CHECK(a.result("history.list", {{"limit", 1}})["steps"][0]["tool"] == tool);
      CHECK(r.contains("hit"));
    }
    CHECK(recoveredDigest(dir, created["session"]) == a.result("session.stats")["digest"]);
  }
  SECTION("refused: a flatten with no surface within the radius, and what the grammar forbids") {
    const std::string before = a.result("session.stats")["digest"];
    const json stroke = a.result("stroke.begin", {{"tool", "flatten"}, {"radius", 3}})["stroke"];
    const json r = a.call("stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", {4, 4, 4}}}}}});
    REQUIRE(r.contains("error"));
    CHECK(r["error"]["code"] == -32602);
    CHECK(r["error"]["data"]["field"] == "dabs[0].center");
    CHECK(r["error"]["message"].get<std::string>().find("no surface") != std::string::npos);
    a.result("stroke.end", {{"stroke", stroke}});
    CHECK(a.error("tool.apply", {{"tool", "contrast"}, {"center", {4, 4, 4}}, {"radius", 3}}) == -32602);
    CHECK(a.error("stroke.begin", {{"tool", "flatten"}, {"height", 2}}) == -32602);
    CHECK(a.error("stroke.begin", {{"tool", "crease"}, {"height", 2}}) == -32602);
    CHECK(a.error("stroke.begin", {{"tool", "inflate"}, {"height", 4}, {"radius", 6}}) == -32602);  // > radius / 2
    CHECK(a.error("stroke.begin", {{"tool", "clay"}, {"strength", 0}}) == -32602);
    CHECK(a.result("session.stats")["digest"] == before);
  }
  fs::remove_all(dir);
}

TEST_CASE("surface tools: presence carries each tool's name to the session's other clients", "[surface][hub]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", {{"size", {32, 32, 32}}, {"solid", "sphere"}});
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  for (const char* tool : {"inflate", "clay", "flatten", "contrast", "crease"}) {
    INFO(tool);
    a.result("presence", {{"brush", {{"tool", tool}, {"radius", 6}, {"point", {16, 27, 16}}, {"normal", {0, 1, 0}},
                                     {"active", true}}}});
    b.link->waitFor([&](const auto& m) {
      return isNotification(m, "presence") && std::get<json>(m)["params"]["brush"]["tool"] == tool;
    });
  }
}

TEST_CASE("surface tools: merged stroke.dabs of a flatten stroke each answer the plane the first dab fitted",
          "[surface][hub]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub);
  a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}});
  const json stroke = a.result("stroke.begin", {{"tool", "flatten"}, {"radius", 6}})["stroke"];
  // A morph keeps the connection busy: the two messages wait behind it and are applied as one.
  const int first = a.nextId;
  a.nextId += 3;
  const auto send = [&](int id, const std::string& method, const json& params) {
    a.hub.text(a.client, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump());
  };
  send(first, "volume.morph", {{"kind", "dilate"}, {"radius", 2}});
  send(first + 1, "stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", {40, 53, 33}}}}}});
  send(first + 2, "stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", {42, 52.5, 33}}}}}});
  std::vector<json> results;
  for (int id = first; id < first + 3; ++id) {
    const json r = std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
    INFO(r.dump());
    REQUIRE(r.contains("result"));
    results.push_back(r["result"]);
  }
  REQUIRE(results[1].contains("plane"));
  CHECK(results[2]["plane"] == results[1]["plane"]);
  CHECK(results[2]["revision"] == results[1]["revision"]);  // one application
  // The plane fitted on the volume as the stroke began (before the morph) at the first dab.
  const Volume begun = makeSolid(SolidKind::Sphere, {64, 64, 64});
  const Plane want = fitBrushPlane(begun, {40, 53, 33}, 6);
  CHECK(results[1]["plane"] == planeJson(want));
}

TEST_CASE("surface tools: the stroke's plane is fitted once, on the starting volume at the first dab that applies",
          "[surface][session]") {
  for (BrushTool tool : {BrushTool::Flatten, BrushTool::Contrast}) {
    Session s(sphere());
    const StrokeId id = s.beginStroke(tool, 5, 1);
    const Vec3 p = onSphere({0.3, 1, 0.2});
    // A dab of pressure 0 and a missed ray apply nothing and fit nothing.
    const ApplyResult none = s.strokeDabs(id, {Dab{p, 0.0}, Dab{Ray{{500, 500, 500}, {1, 0, 0}}}}, ThreadPool::serial());
    CHECK_FALSE(none.changed);
    CHECK_FALSE(none.plane);
    const ApplyResult r = s.strokeDabs(id, {Dab{p, 1.0}, Dab{onSphere({0.4, 1, 0.2}), 1.0}}, ThreadPool::serial());
    REQUIRE(r.plane);
    const Plane want = fitBrushPlane(sphere(), p, 5);
    CHECK(r.plane->point == want.point);
    CHECK(r.plane->normal == want.normal);
    // The sphere's normal there, within the cap's curvature.
    CHECK(dot(r.plane->normal, normalized(p - kCentre)) > 0.99);
    const ApplyResult later = s.strokeDabs(id, {Dab{onSphere({0.6, 1, 0.3}), 1.0}}, ThreadPool::serial());
    REQUIRE(later.plane);
    CHECK(later.plane->point == want.point);
    // Flatten lowers the cap's top under the dab towards the plane, contrast raises it.
    const Int3 top{int(std::lround(p.x)), int(std::lround(p.y)), int(std::lround(p.z))};
    if (tool == BrushTool::Flatten) CHECK(s.volume().at(top) > sphere().at(top) + 0.05);
    else CHECK(s.volume().at(top) < sphere().at(top) - 0.05);
  }
  SECTION("clay with a height rises along the plane's normal: every dab is anchored along it") {
    Session s(sphere());
    const StrokeId id = s.beginStroke(BrushTool::Clay, 6, 1, {}, false, {}, 2.0);
    const ApplyResult r = s.strokeDabs(id, strokeDabs(), ThreadPool::serial());
    REQUIRE(r.plane);
    CHECK(r.plane->normal == fitBrushPlane(sphere(), std::get<Vec3>(strokeDabs()[0].at), 6).normal);
    for (const Vec3& n : r.normals) CHECK(n == r.plane->normal);
    // Add blob with a height anchors each dab along the surface's own normal at its centre.
    Session t(sphere());
    const StrokeId add = t.beginStroke(BrushTool::AddBlob, 6, 1, {}, false, {}, 2.0);
    const ApplyResult b = t.strokeDabs(add, strokeDabs(), ThreadPool::serial());
    CHECK_FALSE(b.plane);
    CHECK(b.normals[0] != b.normals[2]);
  }
  SECTION("inflate with a height moves each point along its own normal: no dab carries one") {
    Session s(sphere());
    const StrokeId id = s.beginStroke(BrushTool::Inflate, 6, 1, {}, false, {}, 2.0);
    const ApplyResult r = s.strokeDabs(id, strokeDabs(), ThreadPool::serial());
    CHECK(r.changed);
    CHECK_FALSE(r.plane);
    for (const Vec3& n : r.normals) CHECK(n == Vec3{});
  }
}

TEST_CASE("surface tools: symmetry mirrors the stroke, pressure scales it, the memory holds a repeated dab back",
          "[surface][session]") {
  for (const Case& c : kCases) {
    INFO(c.name << (c.height ? " with a height" : ""));
    Session mirrored(sphere());
    const StrokeId m = mirrored.beginStroke(c.tool, 5, 1, Symmetry{true, false, false}, false, {}, c.height);
    REQUIRE(mirrored.strokeDabs(m, strokeDabs(), ThreadPool::serial()).changed);
    const Volume& v = mirrored.volume();
    double asymmetry = 0;
    for (int z = 0; z < kN; ++z)
      for (int y = 0; y < kN; ++y)
        for (int x = 0; x < kN; ++x) asymmetry = std::max(asymmetry, double(std::fabs(v.at(x, y, z) - v.at(kN - 1 - x, y, z))));
    CHECK(asymmetry <= 1e-4);
    // The mirrored stroke: the same stroke without symmetry, then its mirror image as a stroke of
    // its own (the two regions share no voxel, and clay's mirrored normal is the image's).
    Session apart(sphere());
    const StrokeId one = apart.beginStroke(c.tool, 5, 1, {}, false, {}, c.height);
    apart.strokeDabs(one, strokeDabs(), ThreadPool::serial());
    apart.endStroke(one);
    CHECK(largestDifference(apart.volume(), sphere()) > 0.2);
    std::vector<Dab> images;
    for (const Dab& d : strokeDabs()) {
      Vec3 q = std::get<Vec3>(d.at);
      q.x = (kN - 1) - q.x;
      images.push_back(Dab{q, 1.0});
    }
    const StrokeId other = apart.beginStroke(c.tool, 5, 1, {}, false, {}, c.height);
    apart.strokeDabs(other, images, ThreadPool::serial());
    CHECK(largestDifference(apart.volume(), v) <= 1e-4);

    // Pressure 0.4 moves the surface less than 1.
    Session light(sphere());
    const StrokeId l = light.beginStroke(c.tool, 5, 1, {}, false, {}, c.height);
    light.strokeDabs(l, strokeDabs(0.4), ThreadPool::serial());
    const double lightMove = largestDifference(light.volume(), sphere());
    CHECK(lightMove > 0.05);
    CHECK(lightMove < largestDifference(apart.volume(), sphere()) - 0.05);

    // The same dabs again in the stroke's next message add nothing: the stroke remembers them.
    const std::uint64_t revision = light.revision();
    CHECK_FALSE(light.strokeDabs(l, strokeDabs(0.4), ThreadPool::serial()).changed);
    CHECK(light.revision() == revision);
  }
}

TEST_CASE("surface tools: a journal replays a flatten stroke a snapshot cut in two, with its plane, to the same digest",
          "[surface][journal]") {
  const fs::path dir = freshDir("snapshot");
  SessionStore store(dir);
  Session live(sphere());
  std::unique_ptr<SessionLog> journal = store.create("s", {"t", "v"}, live.volume());
  const StrokeId id = live.beginStroke(BrushTool::Flatten, 5, 1, Symmetry{true, false, false});
  journal->append(strokeBeginRecord(id, *live.strokeSettings(id)));
  const auto message = [&](const std::vector<Dab>& dabs) {
    const ApplyResult a = live.strokeDabs(id, dabs, ThreadPool::serial());
    REQUIRE(a.changed);
    REQUIRE(a.plane);
    json applied = json::array();
    for (const auto& h : a.hits) applied.push_back({h->x, h->y, h->z, 1.0});
    journal->append({{"r", a.revision}, {"stroke", id}, {"dabs", applied}, {"plane", planeJson(*a.plane)}});
  };
  message({Dab{onSphere({1, 0.6, 0.35}), 1.0}});
  // The snapshot's head re-announces the open stroke with its memory and plane; the volume it
  // was fitted on is gone from the journal.
  std::vector<json> head;
  for (const auto& [sid, params] : live.openStrokeList()) head.push_back(strokeBeginRecord(sid, params));
  REQUIRE(head.size() == 1);
  CHECK(head[0].contains("plane"));
  journal = store.snapshot("s", live.volume(), head);
  message({Dab{onSphere({1, 0.75, 0.35}), 1.0}, Dab{onSphere({1, 0.9, 0.35}), 1.0}});
  journal.reset();
  SessionStore again(dir);
  const Recovered r = again.recover("s", std::size_t(64) << 20, ThreadPool::serial());
  CHECK(r.session->revision() == live.revision());
  CHECK(r.session->digest() == live.digest());
  CHECK(digest(r.session->volume()) == live.digest());
  fs::remove_all(dir);
}

TEST_CASE("surface tools: bad planes and values are refused and change nothing", "[surface][session]") {
  Session s(sphere());
  const std::uint64_t digest0 = s.digest();
  const StrokeId flat = s.beginStroke(BrushTool::Flatten, 3, 1);
  // No surface within 3 vu of the domain's corner: refused, nothing fitted, nothing changed.
  requireError([&] { s.strokeDabs(flat, {Dab{Vec3{4, 4, 4}}}, ThreadPool::serial()); }, protocol::RpcCode::InvalidParams,
               "dabs[0].center");
  requireError([&] { s.strokeDabs(flat, {Dab{onSphere({0, 1, 0.1})}, Dab{Vec3{kNaN, 4, 4}}}, ThreadPool::serial()); },
               protocol::RpcCode::InvalidParams, "dabs[1].center");
  requireError([&] { s.strokeDabs(flat, {Dab{onSphere({0, 1, 0.1}), kNaN}}, ThreadPool::serial()); },
               protocol::RpcCode::InvalidParams, "dabs[0].pressure");
  requireError([&] { s.strokeDabs(flat, {Dab{onSphere({0, 1, 0.1}), 1.5}}, ThreadPool::serial()); },
               protocol::RpcCode::InvalidParams, "dabs[0].pressure");
  CHECK_FALSE(s.strokeSettings(flat)->plane);
  CHECK(s.digest() == digest0);
  CHECK(s.revision() == sphere().revision());
  // A plane given (by a journal) must be finite with a unit normal, and only for the tools that have one.
  requireError([&] { s.setStrokePlane(flat, Plane{{kNaN, 0, 0}, {0, 1, 0}}); }, protocol::RpcCode::InvalidParams, "plane");
  requireError([&] { s.setStrokePlane(flat, Plane{{0, 0, 0}, {0, 2, 0}}); }, protocol::RpcCode::InvalidParams, "plane");
  const StrokeId crease = s.beginStroke(BrushTool::Crease, 3, 1);
  requireError([&] { s.setStrokePlane(crease, Plane{{0, 0, 0}, {0, 1, 0}}); }, protocol::RpcCode::InvalidParams, "plane");
  // Heights only for add and remove blob, inflate and clay.
  for (BrushTool t : {BrushTool::Flatten, BrushTool::Contrast, BrushTool::Crease})
    requireError([&] { s.beginStroke(t, 6, 1, {}, false, {}, 2.0); }, protocol::RpcCode::InvalidParams, "height");
  requireError([&] { s.beginStroke(BrushTool::Clay, 6, kNaN); }, protocol::RpcCode::InvalidParams, "strength");
  requireError([&] { s.beginStroke(BrushTool::Inflate, 6, 1, {}, false, {}, kNaN); }, protocol::RpcCode::InvalidParams,
               "height");
  // A tool.apply flatten where no surface lies within the radius.
  requireError(
      [&] {
        s.apply(protocol::BrushOp{BrushTool::Flatten, BrushParams{{4, 4, 4}, 3, 1}}, ThreadPool::serial());
      },
      protocol::RpcCode::InvalidParams, "center");
  CHECK(s.digest() == digest0);
  // The stroke still fits its plane at its first dab that applies.
  const ApplyResult r = s.strokeDabs(flat, {Dab{onSphere({0, 1, 0.1})}}, ThreadPool::serial());
  CHECK(r.changed);
  CHECK(r.plane);
}
