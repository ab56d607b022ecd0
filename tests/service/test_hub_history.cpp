// Authors, "undo mine", history.list and session.fork through the hub (hub_support.hpp), with
// the data directory recovered alone after each (the journal's records keep the authors and the
// author moves: replay reaches the same digest).
#include <catch2/catch.hpp>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "engine/measures.hpp"
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

HubOptions historyOptions(const fs::path& dir = {}) {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  if (!dir.empty()) o.dataDir = dir;
  return o;
}

fs::path freshDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("marzipan-hub-history-" + name);
  fs::remove_all(d);
  return d;
}

const json kCreate = {{"size", {48, 48, 48}}, {"solid", "sphere"}, {"view", "none"}};
// Two blobs on opposite sides of the sphere (radius ~ 19 around 23.5): no brick in common,
// nor within the tools' margins.
const json kLeftBlob = {{"tool", "add_blob"}, {"center", {6, 24, 24}}, {"radius", 4}};
const json kRightBlob = {{"tool", "add_blob"}, {"center", {41, 24, 24}}, {"radius", 4}};

// The session as a copy of the data directory recovers it (while the hub still runs).
std::unique_ptr<Session> recoverCopy(const fs::path& dir, const std::string& name, const std::string& id) {
  const fs::path copy = freshDir(name + "-copy");
  fs::copy(dir, copy, fs::copy_options::recursive);
  SessionStore store(copy);
  Recovered r = store.recover(id, std::size_t(64) << 20, ThreadPool::serial());
  fs::remove_all(copy);
  return std::move(r.session);
}

std::string hexDigest(const Session& s) { return digestHex(s.volume()); }

}  // namespace

TEST_CASE("each step is recorded with its client as author, and recovery keeps the authors", "[hub][history]") {
  const fs::path dir = freshDir("authors");
  Hub hub(historyOptions(dir));
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", kCreate);
  const std::string id = created["session"];
  b.result("session.join", {{"session", id}, {"token", created["token"]}, {"view", "none"}});
  a.result("tool.apply", kLeftBlob);
  const json stroke = b.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 3}});
  b.result("stroke.dabs", {{"stroke", stroke["stroke"]}, {"dabs", {{{"center", {41, 24, 24}}}, {{"center", {41, 26, 24}}}}}});
  b.result("stroke.end", {{"stroke", stroke["stroke"]}});
  a.result("volume.morph", {{"kind", "dilate"}, {"radius", 1}});
  const std::unique_ptr<Session> rec = recoverCopy(dir, "authors", id);
  const std::vector<StepInfo> steps = rec->steps();
  REQUIRE(steps.size() == 3);
  CHECK(steps[0].author.id == "1");
  CHECK(steps[0].tool == "add_blob");
  CHECK(steps[1].author.id == "2");
  CHECK(steps[2].author.id == "1");
  CHECK(steps[2].tool == "morph");
  CHECK(steps[0].timeMs > 1'700'000'000'000);
  CHECK(steps[0].timeMs <= steps[2].timeMs);
  CHECK(hexDigest(*rec) == a.result("session.stats")["digest"].get<std::string>());
  fs::remove_all(dir);
}
