// ws_roundtrip: what a sculpting client waits for over the WebSocket. An in-process
// net::HttpServer with a service::Hub on 127.0.0.1 (an ephemeral port), Beast WebSocket clients
// on loopback at /ws, a radius-100 sphere in 256^3 (radius 30 in 96^3 with --quick) made by
// makeSphere and sent with volume.load, splats mode. Each `tool.apply` (radius-8 blob, add and
// remove alternating, centred on successive points of a Fibonacci spiral over the sphere) is
// timed from just before its request is written until both its JSON response and its pushed
// splat delta (kind 2, request id 0, the response's revision) have been read.
//
// Three lines: "sessions":1, one client dabbing alone (p50/p99 against the targets of 5 and
// 16 ms); "tool":"grab", one client dragging grab strokes (below); "sessions":8, eight clients,
// each in its own session on its own thread, dabbing at once (throughput and percentiles over
// all their dabs). median_ms/min_ms/max_ms/reps are the per-message round trips. A few warm-up
// messages per session are not counted.
//
// The grab line (issue 29 §5: a grab message's response + delta at p99 <= 16 ms under one
// sculptor): strokes of `grab` at radius 20 (PROTOCOL.md, Warp strokes), each anchored at a
// point of a Fibonacci spiral over the sphere (its first `stroke.dabs`, not timed), then
// `stroke.dabs` messages of one pointer point each, timed as a dab is: the pointer goes round
// the anchor on a circle of 20 vu in the sphere's tangent plane, 30 degrees a message, so every
// message drags the anchor 20 vu from where it began and moves the pointer 10 vu from the last,
// as a sculptor's 60 Hz pointer circling fast; `stroke.end` after every kGrabMessages messages
// and the next stroke elsewhere.
//
// Conventions: the server runs as `marzipan serve` would on opt.threads cores (that many hub
// workers, at most two I/O threads); every wait for a message is bounded, so a server that
// loses one fails the run with what was missing instead of hanging it; a message that breaks
// the order PROTOCOL.md promises (response, then session.changed, then the delta) is counted in
// order_violations, not fatal. This is the only bench file that includes Boost.Beast.
#include <unistd.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <latch>
#include <memory>
#include <numbers>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench.hpp"
#include "engine/solids.hpp"
#include "engine/volume_file.hpp"
#include "net/http_server.hpp"
#include "protocol/cpp/frames.hpp"
#include "service/hub.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace fs = std::filesystem;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;
using nlohmann::json;
using marzipan::protocol::FrameKind;

// Longest wait for any one message; the volume upload on a loaded machine stays well within it.
constexpr auto kWait = std::chrono::seconds(30);
constexpr double kTargetP50Ms = 5, kTargetP99Ms = 16;
constexpr double kBlobRadius = 8;
constexpr double kGrabRadius = 20, kGrabPointer = 20;
constexpr int kGrabMessages = 24;

double msBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

struct Message {
  bool binary = false;
  std::string text;
  std::vector<std::uint8_t> bytes;
  Clock::time_point at;
};

// One WebSocket connection to /ws, driven by its own io_context on the calling thread (one
// thread at a time). Async operations with a deadline stand in for blocking calls, which Asio
// cannot time out.
class WsClient {
 public:
  WsClient(std::uint16_t port, const std::string& session) {
    auto& tcpStream = beast::get_lowest_layer(ws_);
    run("connect", [&](auto done) {
      tcpStream.async_connect(tcp::endpoint(asio::ip::address_v4::loopback(), port), done);
    });
    // The requests are small and each waits for its answers: Nagle would only add delay.
    tcpStream.socket().set_option(tcp::no_delay(true));
    ws_.read_message_max(std::size_t(1) << 30);
    const std::string host = "127.0.0.1:" + std::to_string(port), target = "/ws?session=" + session;
    run("handshake", [&](auto done) { ws_.async_handshake(host, target, done); });
  }

  ~WsClient() {
    if (broken_) return;
    try {
      run("close", [&](auto done) { ws_.async_close(websocket::close_code::normal, done); });
    } catch (const std::exception&) {
      // The server may have closed first (shutdown); nothing is left to tidy.
    }
  }

  WsClient(const WsClient&) = delete;
  WsClient& operator=(const WsClient&) = delete;

  void sendText(const std::string& text) {
    ws_.text(true);
    run("write", [&](auto done) { ws_.async_write(asio::buffer(text), done); });
  }

  void sendBinary(const std::vector<std::uint8_t>& bytes) {
    ws_.binary(true);
    run("write", [&](auto done) { ws_.async_write(asio::buffer(bytes), done); });
  }

  // The next message, stamped when its read completed.
  Message read(const std::string& waitingFor) {
    run(("read (waiting for " + waitingFor + ")").c_str(), [&](auto done) { ws_.async_read(buffer_, done); });
    Message m;
    m.at = Clock::now();
    m.binary = ws_.got_binary();
    const auto data = buffer_.cdata();
    const auto* begin = static_cast<const std::uint8_t*>(data.data());
    if (m.binary) m.bytes.assign(begin, begin + data.size());
    else m.text.assign(reinterpret_cast<const char*>(begin), data.size());
    buffer_.consume(buffer_.size());
    return m;
  }

 private:
  // Starts one async operation and runs the io_context until it completes or kWait passes.
  template <class Start>
  void run(const char* what, Start&& start) {
    if (broken_) throw std::runtime_error(std::string(what) + ": the connection failed before");
    std::optional<beast::error_code> result;
    start([&result](beast::error_code ec, auto&&...) { result = ec; });
    ioc_.restart();
    const auto deadline = Clock::now() + kWait;
    while (!result && ioc_.run_one_until(deadline) > 0) {
    }
    if (!result) {
      // The pending handler refers to `result`: the io_context must never run it now.
      broken_ = true;
      throw std::runtime_error(std::string(what) + ": nothing within " + std::to_string(kWait.count()) + " s");
    }
    if (*result) {
      broken_ = true;
      std::string why = std::string(what) + ": " + result->message();
      if (*result == websocket::error::closed) {
        const websocket::close_reason& reason = ws_.reason();
        why += " (close code " + std::to_string(reason.code) + " \"" +
               std::string(reason.reason.data(), reason.reason.size()) + "\")";
      }
      throw std::runtime_error(why);
    }
  }

  // ioc_ first: the stream goes before the io_context, whose leftover handlers are then
  // destroyed without running.
  asio::io_context ioc_{1};
  websocket::stream<beast::tcp_stream> ws_{ioc_};
  beast::flat_buffer buffer_;
  bool broken_ = false;
};

std::string requestText(std::int64_t id, const char* method, const json& params) {
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump();
}

// Reads until the response to `id`; throws on an error response. Pushes before it are skipped.
json awaitResult(WsClient& ws, std::int64_t id) {
  for (;;) {
    const Message m = ws.read("the response to request " + std::to_string(id));
    if (m.binary) continue;
    const json j = json::parse(m.text);
    if (!j.contains("id")) continue;
    if (j.contains("error") || j["id"] != id)
      throw std::runtime_error("request " + std::to_string(id) + " was answered with " + m.text);
    return j["result"];
  }
}

// Reads until a pushed full splat buffer of this revision.
void awaitFullSplats(WsClient& ws, std::uint64_t revision) {
  for (;;) {
    const Message m = ws.read("the full splat buffer of revision " + std::to_string(revision));
    if (!m.binary) continue;
    const auto decoded = marzipan::protocol::decodeFrameHeader(m.bytes);
    if (!decoded) throw std::runtime_error("unreadable binary frame: " + decoded.error->message);
    const auto& h = decoded.frame->header;
    if (h.kind == FrameKind::SplatsFull && h.requestId == 0 && h.revision == revision) return;
  }
}

// A connection in a new session of the given size holding the .mzv file `volume`, with the
// pushes of creating and loading it read.
std::unique_ptr<WsClient> openSession(std::uint16_t port, const std::string& session, int side,
                                      const std::vector<std::uint8_t>& volume) {
  auto ws = std::make_unique<WsClient>(port, session);
  // An empty solid: the sphere comes from the file, so that its radius is exactly the one asked.
  ws->sendText(requestText(1, "session.create", {{"size", {side, side, side}}, {"solid", "empty"}, {"session", session}}));
  const json created = awaitResult(*ws, 1);
  awaitFullSplats(*ws, created["revision"].get<std::uint64_t>());
  ws->sendText(requestText(2, "volume.load", {{"bytes", volume.size()}}));
  ws->sendBinary(marzipan::protocol::encodeFrame(FrameKind::VolumeUpload, 2, 0, volume));
  const json loaded = awaitResult(*ws, 2);
  awaitFullSplats(*ws, loaded["revision"].get<std::uint64_t>());
  return ws;
}

// Dab i of a run: a point of the Fibonacci spiral of `count` points over the sphere; even dabs
// add, odd dabs remove, so the solid stays near the sphere however many run.
struct DabPlan {
  double center, radius;
  int count;
  // The unit vector from the sphere's centre to point i.
  std::array<double, 3> direction(int i) const {
    const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
    const int k = i % count;
    const double y = 1 - 2 * (k + 0.5) / count, r = std::sqrt(1 - y * y), phi = golden * k;
    return {r * std::cos(phi), y, r * std::sin(phi)};
  }
  json point(int i) const {
    const auto n = direction(i);
    return {center + radius * n[0], center + radius * n[1], center + radius * n[2]};
  }
  json params(int i) const {
    return {{"tool", i % 2 ? "remove_blob" : "add_blob"}, {"center", point(i)}, {"radius", kBlobRadius}};
  }
};

struct DabTiming {
  double roundTripMs = 0, responseMs = 0;
  bool changed = true;
  int orderViolations = 0;
  std::size_t deltaBytes = 0;
};

// One request that changes the volume (`tool.apply`, `stroke.dabs`), timed until its response
// and (when it changed something) its delta arrived.
DabTiming timedChange(WsClient& ws, std::int64_t id, const char* method, const json& params) {
  const std::string text = requestText(id, method, params);
  DabTiming t;
  std::optional<std::uint64_t> revision, deltaRevision;
  std::optional<Clock::time_point> responseAt, deltaAt;
  // Arrival positions of the three messages, to check the order PROTOCOL.md promises.
  int seq = 0, responseSeq = -1, changedSeq = -1, deltaSeq = -1;
  const auto t0 = Clock::now();
  ws.sendText(text);
  while (!responseAt || (t.changed && !deltaAt)) {
    const std::string waiting = responseAt ? "the splat delta of revision " + std::to_string(*revision)
                                           : std::string("the response to ") + method + " " + std::to_string(id);
    const Message m = ws.read(waiting);
    ++seq;
    if (m.binary) {
      const auto decoded = marzipan::protocol::decodeFrameHeader(m.bytes);
      if (!decoded) throw std::runtime_error("unreadable binary frame: " + decoded.error->message);
      const auto& h = decoded.frame->header;
      if (h.kind != FrameKind::SplatsDelta || h.requestId != 0 || deltaAt)
        throw std::runtime_error("while waiting for " + waiting + ": an extra frame of kind " +
                                 std::to_string(int(h.kind)) + ", request id " + std::to_string(h.requestId) +
                                 ", revision " + std::to_string(h.revision));
      deltaRevision = h.revision;
      deltaAt = m.at;
      deltaSeq = seq;
      t.deltaBytes = m.bytes.size();
    } else {
      const json j = json::parse(m.text);
      if (j.contains("id")) {
        if (j.contains("error") || j["id"] != id)
          throw std::runtime_error(std::string(method) + " " + std::to_string(id) + " " + params.dump() +
                                   " was answered with " + m.text);
        responseAt = m.at;
        responseSeq = seq;
        revision = j["result"]["revision"].get<std::uint64_t>();
        t.changed = !j["result"]["roi"].is_null();
      } else if (j.value("method", "") == "session.changed") {
        changedSeq = seq;
      }
    }
    if (revision && deltaRevision && *deltaRevision != *revision)
      throw std::runtime_error(std::string(method) + " " + std::to_string(id) + " made revision " +
                               std::to_string(*revision) +
                               ", the delta pushed with it shows revision " + std::to_string(*deltaRevision));
  }
  if (t.changed && !(responseSeq < changedSeq && changedSeq < deltaSeq)) t.orderViolations = 1;
  t.responseMs = msBetween(t0, *responseAt);
  t.roundTripMs = msBetween(t0, t.changed ? std::max(*responseAt, *deltaAt) : *responseAt);
  return t;
}

// Nearest-rank percentile of sorted values.
double percentile(const std::vector<double>& sorted, double p) {
  const auto rank = std::size_t(std::ceil(p / 100 * double(sorted.size())));
  return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

struct Summary {
  std::vector<double> roundTrips, responses;
  int unchanged = 0, orderViolations = 0;
  std::size_t deltaBytes = 0;
  void add(const DabTiming& t) {
    roundTrips.push_back(t.roundTripMs);
    responses.push_back(t.responseMs);
    unchanged += t.changed ? 0 : 1;
    orderViolations += t.orderViolations;
    deltaBytes += t.deltaBytes;
  }
  void add(const Summary& s) {
    roundTrips.insert(roundTrips.end(), s.roundTrips.begin(), s.roundTrips.end());
    responses.insert(responses.end(), s.responses.begin(), s.responses.end());
    unchanged += s.unchanged;
    orderViolations += s.orderViolations;
    deltaBytes += s.deltaBytes;
  }
  // The harness's timing fields over the round trips (its max_ms is the slowest dab).
  marzipan::bench::Timing timing() {
    sort();
    return {percentile(roundTrips, 50), roundTrips.front(), roundTrips.back(), int(roundTrips.size())};
  }
  // The distribution beside them; the p50 target is the blob dabs' only (the grab has none).
  nlohmann::ordered_json figures(bool p50Target = true) {
    sort();
    const double n = double(roundTrips.size());
    const double p50 = percentile(roundTrips, 50), p99 = percentile(roundTrips, 99);
    nlohmann::ordered_json out{{"dabs", roundTrips.size()},
                               {"p50_ms", p50},
                               {"p99_ms", p99},
                               {"mean_ms", std::accumulate(roundTrips.begin(), roundTrips.end(), 0.0) / n},
                               {"response_p50_ms", percentile(responses, 50)},
                               {"response_p99_ms", percentile(responses, 99)},
                               {"delta_bytes_mean", double(deltaBytes) / n},
                               {"unchanged", unchanged},
                               {"order_violations", orderViolations}};
    if (p50Target) out["target_p50_ms"] = kTargetP50Ms;
    out["target_p99_ms"] = kTargetP99Ms;
    if (p50Target) out["p50_met"] = p50 <= kTargetP50Ms;
    out["p99_met"] = p99 <= kTargetP99Ms;
    return out;
  }
  void sort() {
    std::sort(roundTrips.begin(), roundTrips.end());
    std::sort(responses.begin(), responses.end());
  }
};

// `count` timed dabs starting at plan index `first`; request ids continue from `nextId`.
Summary sculpt(WsClient& ws, const DabPlan& plan, int first, int count, std::int64_t& nextId) {
  Summary s;
  for (int i = 0; i < count; ++i) s.add(timedChange(ws, nextId++, "tool.apply", plan.params(first + i)));
  return s;
}

// `strokes` grab strokes anchored at plan's points from `first` on, kGrabMessages timed
// pointer messages each (the header).
Summary grabStrokes(WsClient& ws, const DabPlan& plan, int first, int strokes, std::int64_t& nextId) {
  Summary s;
  for (int k = first; k < first + strokes; ++k) {
    const std::int64_t begin = nextId++;
    ws.sendText(requestText(begin, "stroke.begin", {{"tool", "grab"}, {"radius", kGrabRadius}}));
    const std::uint64_t stroke = awaitResult(ws, begin)["stroke"].get<std::uint64_t>();
    // The anchor: changes nothing, so no delta follows its response.
    const std::int64_t anchorId = nextId++;
    const json anchor = plan.point(k);
    ws.sendText(requestText(anchorId, "stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", anchor}}}}}));
    awaitResult(ws, anchorId);
    // Two unit vectors of the tangent plane at the anchor.
    using V3 = std::array<double, 3>;
    const auto cross = [](const V3& a, const V3& b) {
      return V3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    };
    const V3 n = plan.direction(k);
    V3 t1 = cross(n, std::fabs(n[1]) < 0.9 ? V3{0, 1, 0} : V3{1, 0, 0});
    const double l = std::sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    for (double& c : t1) c /= l;
    const V3 t2 = cross(n, t1);
    for (int m = 0; m < kGrabMessages; ++m) {
      const double angle = std::numbers::pi / 6 * m;
      const double c = std::cos(angle) * kGrabPointer, d = std::sin(angle) * kGrabPointer;
      json pointer = json::array();
      for (int a = 0; a < 3; ++a) pointer.push_back(anchor[a].get<double>() + c * t1[a] + d * t2[a]);
      s.add(timedChange(ws, nextId++, "stroke.dabs", {{"stroke", stroke}, {"dabs", {{{"center", pointer}}}}}));
    }
    const std::int64_t end = nextId++;
    ws.sendText(requestText(end, "stroke.end", {{"stroke", stroke}}));
    awaitResult(ws, end);
  }
  return s;
}

// An empty web root in the temporary directory: the server needs one, the bench serves nothing.
struct ScratchDir {
  fs::path path = fs::temp_directory_path() / ("marzipan-bench-ws-" + std::to_string(::getpid()));
  ScratchDir() { fs::create_directories(path); }
  ~ScratchDir() {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
};

MARZIPAN_BENCH("ws_roundtrip") {
  using namespace marzipan;
  const int side = opt.quick ? 96 : 256;
  const double radius = opt.quick ? 30 : 100;
  const int singleDabs = opt.quick ? 20 : 500, parallelSessions = 8, parallelDabs = opt.quick ? 5 : 250;
  const int warmUp = opt.quick ? 2 : 10;
  // Grab strokes of kGrabMessages timed messages each (the warm-up stroke is not counted).
  const int grabStrokeCount = opt.quick ? 2 : 20;
  const double center = (side - 1) / 2.0;
  const std::vector<std::uint8_t> volume = saveVolume(makeSphere({side, side, side}, {center, center, center}, radius));

  const ScratchDir webRoot;
  service::HubOptions hubOptions;
  hubOptions.workers = unsigned(opt.threads);
  service::Hub hub(hubOptions);
  net::HttpServerOptions serverOptions;
  serverOptions.port = 0;
  serverOptions.webRoot = webRoot.path;
  serverOptions.threads = std::min(2u, unsigned(opt.threads));
  serverOptions.hub = &hub;
  // Connection events would interleave with the bench's output; failures surface in the client.
  serverOptions.log = [](const std::string&) {};
  net::HttpServer server(serverOptions);
  server.start();
  const std::uint16_t port = server.port();

  const nlohmann::ordered_json common{{"volume", side}, {"radius", radius}, {"blob_radius", kBlobRadius},
                                      {"volume_file_bytes", volume.size()}};
  // Warm-up dabs (first allocations, caches) on a spiral of their own, not timed.
  const DabPlan warmUpPlan{center, radius, warmUp};
  {
    const DabPlan plan{center, radius, singleDabs};
    Summary s;
    {
      const auto ws = openSession(port, "bench-ws-roundtrip-single", side, volume);
      std::int64_t id = 100;
      sculpt(*ws, warmUpPlan, 0, warmUp, id);
      s = sculpt(*ws, plan, 0, singleDabs, id);
    }
    const bench::Timing t = s.timing();
    nlohmann::ordered_json extra{{"sessions", 1}};
    extra.update(common);
    extra.update(s.figures());
    bench::emit("ws_roundtrip", opt.threads, t, extra);
  }
  {
    const DabPlan plan{center, radius, grabStrokeCount};
    Summary s;
    {
      const auto ws = openSession(port, "bench-ws-roundtrip-grab", side, volume);
      std::int64_t id = 100;
      grabStrokes(*ws, DabPlan{center, radius, 1}, 0, 1, id);
      s = grabStrokes(*ws, plan, 0, grabStrokeCount, id);
    }
    const bench::Timing t = s.timing();
    nlohmann::ordered_json extra{{"sessions", 1}, {"tool", "grab"}, {"grab_radius", kGrabRadius},
                                 {"pointer_vu", kGrabPointer}, {"messages_per_stroke", kGrabMessages}};
    extra.update(common);
    extra.update(s.figures(false));
    bench::emit("ws_roundtrip", opt.threads, t, extra);
  }
  {
    const DabPlan plan{center, radius, parallelSessions * parallelDabs};
    std::vector<std::unique_ptr<WsClient>> clients;
    std::vector<std::int64_t> ids(parallelSessions, 100);
    for (int i = 0; i < parallelSessions; ++i) {
      clients.push_back(openSession(port, "bench-ws-roundtrip-parallel-" + std::to_string(i), side, volume));
      sculpt(*clients.back(), warmUpPlan, 0, warmUp, ids[i]);
    }
    std::vector<Summary> summaries(parallelSessions);
    std::vector<std::exception_ptr> errors(parallelSessions);
    std::latch go(1);
    std::vector<std::thread> threads;
    for (int i = 0; i < parallelSessions; ++i) {
      threads.emplace_back([&, i] {
        try {
          go.wait();
          // Each session dabs its own stretch of the spiral, so no two run the same sequence.
          summaries[i] = sculpt(*clients[i], plan, i * parallelDabs, parallelDabs, ids[i]);
        } catch (...) {
          errors[i] = std::current_exception();
        }
      });
    }
    const auto t0 = Clock::now();
    go.count_down();
    for (auto& th : threads) th.join();
    const double wallMs = msBetween(t0, Clock::now());
    for (const auto& e : errors)
      if (e) std::rethrow_exception(e);
    clients.clear();
    Summary all;
    for (const Summary& s : summaries) all.add(s);
    const bench::Timing t = all.timing();
    nlohmann::ordered_json extra{{"sessions", parallelSessions}, {"dabs_per_session", parallelDabs}};
    extra.update(common);
    extra.update(all.figures());
    extra["wall_ms"] = wallMs;
    extra["dabs_per_s"] = parallelSessions * parallelDabs / (wallMs / 1000);
    bench::emit("ws_roundtrip", opt.threads, t, extra);
  }
  server.stop();
}

}  // namespace
