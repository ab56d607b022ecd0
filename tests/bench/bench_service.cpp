// dab_message: one browser-like stroke.dabs message as the hub handles it,
// without the socket (issue 32: the per-application overhead outside the
// engine). A service::Hub in process, as `marzipan serve` runs it without
// --data-dir (no journal, as the load tool's server), with opt.threads workers;
// three splats-mode clients reading splat format version 2 (as the web and load
// clients) in one session of the 256^3 `sphere` solid (radius 89.6; 64^3 with
// --quick): three sculptors to a session, as the load tool's 48 / 16. Each
// client draws add-blob strokes of radius 8 as the web client sends them
// (strength 0.5, so a height of 2 vu; dabs 2 vu apart, a quarter of the radius,
// two to a message) along a great circle from a random point of a cap of the
// sphere, kStrokeMessages messages a stroke. The clients take turns message by
// message and their strokes cross, so the session's steps fold and seal by the
// hub's own rules (History::fold): `session_undo_steps` of `strokes` strokes.
//
// Timed (measurement): from hub.text() of the request until every client's link
// has been handed the change's splat delta and the requester its response, with
// the stroke's stroke.begin and stroke.end on its first and last message:
// parsing, the strand, the engine's stroke, the undo fold and sealing, the
// digest, the bricks around the change, the delta's extraction, HeldSplats and
// the frame, the notification's JSON, the hand-overs to the links (BenchLink:
// counts, keeps nothing). One message per application (the next is sent when
// the last is answered: nothing to merge). session_measurement: the same
// messages as Session::strokeDabs alone (with beginStroke / endStroke alike) on
// a Session of the same volume: the engine, the fold and sealing, the digest
// and the bricks around; the difference is the hub's broadcast, JSON and
// hand-overs. Instructions (tests/bench/instructions.py) count the calling
// thread and the hub's worker, which starts counting at its first hand-over (in
// the untimed first message): with --threads 1 that is all of the work; with
// more, the engine pool's other threads hand nothing over and go uncounted, and
// the Session alone runs on one thread whatever --threads says.
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench.hpp"
#include "engine/solids.hpp"
#include "protocol/cpp/splats.hpp"
#include "service/hub.hpp"
#include "service/session.hpp"

namespace marzipan::bench {

namespace {

using nlohmann::json;

constexpr int kClients = 3;
constexpr int kStrokeMessages = 12;
constexpr int kDabsPerMessage = 2;
constexpr double kRadius = 8, kStrength = 0.5, kHeight = 2, kSpacing = 2;
constexpr double kCapSpread = 0.4;

// Counts what the hub hands one client's connection; keeps the texts only while
// asked to (setup: the answers whose fields the bench reads).
struct BenchLink : service::ClientLink {
  std::mutex mutex;
  std::condition_variable cv;
  int texts = 0, binaries = 0;
  bool keep = false;
  std::vector<std::string> kept;

  // Under callgrind, whether a thread of the hub that hands something over
  // starts collecting (callgrind's collection is per thread; measure() toggles
  // only the bench's own).
  static inline std::atomic<bool> countWorkers{false};
  static inline std::thread::id benchThread;

  void note(const std::string* text, bool binary) {
    thread_local bool collecting = false;
    if (countWorkers && !collecting && std::this_thread::get_id() != benchThread) {
      toggleInstructionCount();
      collecting = true;
    }
    const std::lock_guard lock(mutex);
    if (text) {
      ++texts;
      if (keep) kept.push_back(*text);
    }
    if (binary) ++binaries;
    cv.notify_all();
  }
  void sendText(std::string text) override { note(&text, false); }
  void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>>, bool) override { note(nullptr, true); }
  void sendTogether(std::vector<Message> messages) override {
    for (const Message& m : messages) note(m.text.get(), m.binary != nullptr);
  }
  void sendAll(std::vector<Item> items) override {
    for (const Item& i : items) note(i.text.get(), i.binary != nullptr);
  }
  void close(int, std::string) override {}

  // Waits until at least `t` texts and `b` binaries arrived (bounded: a lost
  // message fails the run).
  void waitFor(int t, int b) {
    std::unique_lock lock(mutex);
    if (!cv.wait_for(lock, std::chrono::seconds(60), [&] { return texts >= t && binaries >= b; }))
      throw std::runtime_error("dab_message: the hub did not answer");
  }
  // The kept text whose "id" is `id` (setup only).
  json answer(int id) {
    std::unique_lock lock(mutex);
    json found;
    cv.wait_for(lock, std::chrono::seconds(60), [&] {
      for (const std::string& t : kept) {
        json j = json::parse(t);
        if (j.value("id", json()) == id) {
          found = std::move(j);
          return true;
        }
      }
      return false;
    });
    if (!found.contains("result")) throw std::runtime_error("dab_message: request " + std::to_string(id) + " failed");
    return found["result"];
  }
};

std::string request(int id, const char* method, const json& params) {
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump();
}

// One client's strokes: dab positions along great circles of the sphere,
// kDabsPerMessage a message, a new circle from a random point every
// kStrokeMessages messages.
struct StrokePath {
  Vec3 centre;
  double radius;
  Vec3 u, v;  // the circle's plane, orthonormal
  double angle = 0;

  // From a random point of the cap around +z where the clients work
  // (kCapSpread: its spread), so that their strokes cross and a message that
  // meets another's newer step seals its own.
  void restart(std::mt19937& rng) {
    std::normal_distribution<double> gauss;
    u = normalized(Vec3{gauss(rng), gauss(rng), gauss(rng)} * kCapSpread + Vec3{0, 0, 1});
    const Vec3 w = normalized({gauss(rng), gauss(rng), gauss(rng)});
    v = normalized(w - u * dot(w, u));
    angle = 0;
  }
  Vec3 next() {
    const Vec3 p = centre + (u * std::cos(angle) + v * std::sin(angle)) * radius;
    angle += kSpacing / radius;
    return p;
  }
};

}  // namespace

MARZIPAN_BENCH("dab_message") {
  const int side = opt.quick ? 64 : 256;
  const int messages = opt.quick ? 2 * kStrokeMessages : 20 * kStrokeMessages;
  const Vec3 centre{(side - 1) / 2.0, (side - 1) / 2.0, (side - 1) / 2.0};
  const double radius = 0.35 * side;

  service::HubOptions o;
  o.workers = unsigned(std::max(1, opt.threads));
  service::Hub hub(o);
  std::vector<std::shared_ptr<BenchLink>> links;
  std::vector<std::shared_ptr<service::HubClient>> clients;
  for (int k = 0; k < kClients; ++k) {
    links.push_back(std::make_shared<BenchLink>());
    links.back()->keep = true;
    clients.push_back(hub.connect(links.back(), "bench"));
  }
  int id = 1;
  const json view{{"view", "splats"}, {"splats", kSplatFormatVersion}};
  json create{{"size", {side, side, side}}, {"solid", "sphere"}};
  create.update(view);
  hub.text(clients[0], request(id, "session.create", create));
  const json created = links[0]->answer(id++);
  for (int k = 1; k < kClients; ++k) {
    json join{{"session", created["session"]}, {"token", created["token"]}};
    join.update(view);
    hub.text(clients[k], request(id, "session.join", join));
    links[k]->answer(id++);
  }
  const json strokeParams{{"tool", "add_blob"}, {"radius", kRadius}, {"strength", kStrength}, {"height", kHeight}};

  std::mt19937 rng{21};
  std::vector<StrokePath> paths(kClients, StrokePath{centre, radius, {}, {}});
  std::vector<std::uint64_t> strokes(kClients, 0);
  std::vector<int> sent(kClients, 0);
  // Every message's dabs in order, and which client sent it, for the
  // Session-alone run.
  std::vector<std::vector<Vec3>> dabsOf;
  std::vector<int> clientOf;
  int next = 0;
  // The next message's texts, made before it is timed: a client's JSON is not the server's work.
  // A stroke's stroke.begin and stroke.end go with its first and last message (the load tool's
  // clients send them too); the strokes' ids are 1, 2, ... in the order they begin.
  std::uint64_t begun = 0;
  std::string beginText, dabsText, endText;
  auto drawMessage = [&] {
    const int k = next;
    const bool first = sent[k] % kStrokeMessages == 0, last = (sent[k] + 1) % kStrokeMessages == 0;
    if (first) paths[k].restart(rng);
    std::vector<Vec3> dabs;
    for (int d = 0; d < kDabsPerMessage; ++d) dabs.push_back(paths[k].next());
    beginText.clear();
    if (first) {
      beginText = request(id++, "stroke.begin", strokeParams);
      strokes[k] = ++begun;
    }
    json list = json::array();
    for (const Vec3& p : dabs) list.push_back({{"center", {p.x, p.y, p.z}}, {"pressure", 1}});
    dabsText = request(id++, "stroke.dabs", {{"stroke", strokes[k]}, {"dabs", std::move(list)}});
    endText = last ? request(id++, "stroke.end", {{"stroke", strokes[k]}}) : std::string();
    dabsOf.push_back(std::move(dabs));
    clientOf.push_back(k);
  };
  // Client k's request `text`, waiting for its answer and, for a change, every
  // client's delta.
  auto call = [&](int k, const std::string& text, bool change) {
    std::vector<int> texts(kClients), binaries(kClients);
    for (int j = 0; j < kClients; ++j) {
      const std::lock_guard lock(links[j]->mutex);
      texts[j] = links[j]->texts + (j == k) + (change ? 1 : 0);  // the response, session.changed
      binaries[j] = links[j]->binaries + (change ? 1 : 0);       // the splat delta
    }
    hub.text(clients[k], text);
    for (int j = 0; j < kClients; ++j) links[j]->waitFor(texts[j], binaries[j]);
  };
  auto send = [&] {
    const int k = next;
    if (!beginText.empty()) call(k, beginText, false);
    call(k, dabsText, true);
    if (!endText.empty()) call(k, endText, false);
    ++sent[k];
    next = (k + 1) % kClients;
  };
  for (const auto& l : links) {
    const std::lock_guard lock(l->mutex);
    l->keep = false;
    l->kept.clear();
  }
  // Under callgrind the hub's worker counts from its first hand-over on (an
  // untimed message): it collects all the time, what the timed calls make it do
  // and nothing else.
  BenchLink::benchThread = std::this_thread::get_id();
  if (countingInstructions()) BenchLink::countWorkers = true;
  drawMessage();
  send();
  const Timing hubTiming = measure(messages, drawMessage, send);
  BenchLink::countWorkers = false;

  // The same messages on a Session alone.
  ThreadPool serial(1);
  service::Session session(makeSolid(SolidKind::Sphere, {side, side, side}, Volume::kDefaultBand, serial),
                           service::HubLimits{}.historyBytes);
  std::vector<service::StrokeId> own(kClients, 0);
  std::vector<int> count(kClients, 0);
  std::size_t m = 0;
  std::vector<service::Dab> message;
  auto apply = [&] {
    const int k = clientOf[m];
    message.clear();
    for (const Vec3& p : dabsOf[m]) message.emplace_back(p, 1.0);
    if (count[k] % kStrokeMessages == 0)
      own[k] = session.beginStroke(protocol::BrushTool::AddBlob, kRadius, kStrength, {}, false,
                                   service::StepAuthor{std::to_string(k + 1), ""}, kHeight);
    session.strokeDabs(own[k], message, ThreadPool::serial());
    if (++count[k] % kStrokeMessages == 0) session.endStroke(own[k]);
    ++m;
  };
  apply();
  const Timing sessionTiming = measure(messages, apply);
  emit("dab_message", opt.threads, hubTiming,
       {{"side", side},
        {"clients", kClients},
        {"dab_radius", kRadius},
        {"dabs_per_message", kDabsPerMessage},
        {"strokes", begun},
        {"session_undo_steps", session.steps().size()},
        {"session_history_bytes", session.history().bytes()},
        {"session_median_ms", sessionTiming.median_ms},
        {"session_measurement", sessionTiming.measurement}});
}

}  // namespace marzipan::bench
