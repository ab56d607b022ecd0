// marzipan-load-client: N sculpting clients on M sessions of a running `marzipan serve`, each
// sculpting as the browser does (marzipan_load.py's web-client mode, the same strokes from the
// same seed: web_client_model.hpp), all on one thread, so that one core drives 128 of them. The
// load tool starts it (marzipan_load.py --client-bin) in place of its Python client processes
// and makes the report; it is not meant to be run alone.
//
//   marzipan-load-client --url ws://HOST:PORT/ws --clients N --sessions ID,ID,... [--size 128]
//       [--solid pig] [--seed 1] [--duration 60] [--dab-spacing 0.25]
//     Client i works in session i mod M (the first of each creates it, the others join with its
//     token, all in splats view). Prints "ready" once every client is in its session, reads a
//     line "start T0" (T0 in seconds of CLOCK_MONOTONIC, time.monotonic()'s clock), sculpts
//     from T0 for the duration, waits for the answers and last deltas still due, and prints
//     one JSON line: what marzipan_load.py's client processes return (latencies in seconds).
//   marzipan-load-client --plan SPLATS_FILE --client I [--seed 1] [--size 128] [--strokes 4]
//       [--dab-spacing 0.25]
//     The first strokes of client I on the splat buffer in SPLATS_FILE (no server), one JSON
//     line each: its parameters and the dabs of each pointer event, for checking against the
//     Python model (test_load_client.py).
//
// What a client does, and what it measures, is marzipan_load.py's LoadClient in web-client
// mode: a pointer event every 1/60 s during a stroke, its dabs queued until stroke.begin has
// answered, then every event and every answer sends all waiting dabs as one stroke.dabs unless
// 3 are unanswered; stroke.end once nothing waits or is in flight; the next stroke 0.25 s later.
// Latencies are stamped when a message's read completes. Exit status: 0 when the run could be
// made (its errors are in the JSON), 1 when setup failed, 2 for usage errors.
#include <sys/resource.h>

#include <algorithm>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "web_client_model.hpp"

namespace marzipan::load {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

constexpr double kSetupTimeoutS = 60, kDrainTimeoutS = 10, kCloseTimeoutS = 5;
constexpr std::size_t kMaxMessageBytes = std::size_t(64) << 20;
// The splat format version the browser asks for (SPLAT_FORMAT_VERSION, web-client/net/session-client.js).
constexpr int kSplatsVersion = 2;

double now() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }
Clock::time_point at(double seconds) {
  return Clock::time_point(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)));
}

double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Seconds this process's threads waited for a core (schedstat's second field), or null.
json runqueueWaitS() {
  double total = 0;
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task", ec)) {
    std::ifstream f(task.path() / "schedstat");
    double run = 0, wait = 0;
    if (!(f >> run >> wait)) return nullptr;
    total += wait;
  }
  return ec ? json(nullptr) : json(total / 1e9);
}

json dabJson(const WireDab& d) {
  if (d.isRay)
    return {{"ray", {{"origin", {d.at[0], d.at[1], d.at[2]}}, {"direction", {d.direction[0], d.direction[1], d.direction[2]}}}},
            {"pressure", d.pressure}};
  return {{"center", {d.at[0], d.at[1], d.at[2]}}, {"pressure", d.pressure}};
}

json paramsJson(const StrokeParams& p) {
  json j{{"tool", p.tool}, {"radius", p.radius}, {"strength", p.strength}};
  if (p.height) j["height"] = *p.height;
  if (p.accumulate) j["accumulate"] = true;
  return j;
}

struct Config {
  std::string host, port, path;
  int clients = 0;
  std::vector<std::string> sessions;
  int size = 128;
  std::string solid = "pig";
  std::uint32_t seed = 1;
  double duration = 60, dabSpacing = kDabSpacing;
};

// What all clients count, as marzipan_load.py's WorkerStats.
struct Stats {
  bool closing = false;
  std::map<std::string, long> sent, errors, notifications, anomalies, unexpectedCloses, strokeTools;
  json errorSamples = json::array();
  long answered = 0, dabsApplied = 0, deltas = 0, deltaBytes = 0, fullBuffers = 0, pointerEvents = 0;
  std::vector<double> dabsLatency, dabsSent, deltaLatency, dabDeltaLatency, sendLag, loopLag;
  std::vector<int> dabsPerMessage;
  std::map<int, std::vector<double>> sessionDabsLatency, sessionDeltaLatency;
  std::map<std::string, std::vector<double>> otherLatency;
};

class Client;

struct Session {
  int index = 0;
  std::string id;
  json token;
  bool created = false;
  std::vector<Client*> waiting;  // to join once it is created
  long lastRevision = 0;         // newest revision any of its clients' dabs made
  std::set<long> dabRevisions;   // one per application
  SplatSurface surface;          // as its creating client receives it
};

class Client {
 public:
  // Called with the result, or with the error object, or with neither when the connection closed.
  using Done = std::function<void(const json* result, const json* error)>;

  Client(asio::io_context& io, int index, Session& session, bool creator, const Config& cfg, Stats& stats)
      : index_(index), session_(session), creator_(creator), cfg_(cfg), stats_(stats), ws_(io), timer_(io),
        rng_(std::uint32_t(cfg.seed * 100003u + std::uint32_t(index))) {}

  bool ready = false, sculptDone = false;
  std::string setupError;

  void enter(const tcp::resolver::results_type& endpoints) {
    beast::get_lowest_layer(ws_).async_connect(endpoints, [this](beast::error_code ec, const tcp::endpoint&) {
      if (ec) return fail("connect: " + ec.message());
      // Small messages each waited for: Nagle would only add delay (asyncio sets this too).
      beast::get_lowest_layer(ws_).socket().set_option(tcp::no_delay(true));
      ws_.read_message_max(kMaxMessageBytes);
      ws_.async_handshake(cfg_.host + ":" + cfg_.port, cfg_.path + "?session=" + session_.id, [this](beast::error_code shook) {
        if (shook) return fail("handshake: " + shook.message());
        read();
        if (creator_) {
          const json params{{"size", {cfg_.size, cfg_.size, cfg_.size}}, {"solid", cfg_.solid}, {"session", session_.id}, {"view", "splats"}, {"splats", kSplatsVersion}};
          send("session.create", params, [this](const json* result, const json* error) {
            if (!result) return fail("session.create: " + (error ? error->dump() : std::string("closed")));
            session_.token = (*result)["token"];
            session_.created = true;
            ready = true;
            for (Client* c : session_.waiting) c->join();
          });
        } else if (session_.created) {
          join();
        } else {
          session_.waiting.push_back(this);
        }
      });
    });
  }

  void startSculpting(double start, double end) {
    end_ = end;
    timer_.expires_at(at(start));
    timer_.async_wait([this](beast::error_code ec) {
      if (!ec) beginStroke();
    });
  }

  bool hasPending() const { return !pending_.empty() && !closed_; }
  std::size_t pendingCount() const { return pending_.size(); }
  bool closed() const { return closed_; }
  long lastDeltaRevision() const { return lastDeltaRevision_; }
  Session& session() { return session_; }
  bool creator() const { return creator_; }
  int index() const { return index_; }

  void send(const std::string& method, const json& params, Done done = {}, std::vector<double> dabTimes = {}) {
    const long id = nextId_++;
    const double sent = now();
    outbox_.push_back(json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump());
    pending_[id] = {method, sent, std::move(done), std::move(dabTimes)};
    ++stats_.sent[method];
    write();
  }

  void close(std::function<void()> done) {
    if (closed_) return done();
    ws_.async_close(websocket::close_code::normal, [done](beast::error_code) { done(); });
  }

 private:
  struct Pending {
    std::string method;
    double sent;
    Done done;
    std::vector<double> dabTimes;
  };
  struct Awaiting {
    long revision;
    double sent;
    std::vector<double> dabTimes;
  };

  void fail(const std::string& why) {
    if (setupError.empty()) setupError = "client " + std::to_string(index_) + ": " + why;
  }

  void join() {
    const json params{{"session", session_.id}, {"token", session_.token}, {"view", "splats"}, {"splats", kSplatsVersion}};
    send("session.join", params, [this](const json* result, const json* error) {
      if (!result) return fail("session.join: " + (error ? error->dump() : std::string("closed")));
      ready = true;
    });
  }

  void write() {
    if (writing_ || outbox_.empty() || closed_) return;
    writing_ = true;
    ws_.text(true);
    ws_.async_write(asio::buffer(outbox_.front()), [this](beast::error_code ec, std::size_t) {
      writing_ = false;
      outbox_.pop_front();
      if (!ec) write();  // a failed write shows as the read's end
    });
  }

  void read() {
    ws_.async_read(buffer_, [this](beast::error_code ec, std::size_t) {
      if (ec) return ended(ec);
      const double t = now();
      const auto data = buffer_.cdata();
      const auto* bytes = static_cast<const std::uint8_t*>(data.data());
      if (ws_.got_text()) {
        onText(std::string_view(reinterpret_cast<const char*>(bytes), data.size()), t);
      } else {
        onBinary(std::span<const std::uint8_t>(bytes, data.size()), t);
      }
      buffer_.consume(buffer_.size());
      read();
    });
  }

  // The connection ended: fails whatever waited on it and ends the sculpting.
  void ended(beast::error_code ec) {
    closed_ = true;
    if (!stats_.closing) {
      const int code = ec == websocket::error::closed ? int(ws_.reason().code) : 1006;
      ++stats_.unexpectedCloses[std::to_string(code)];
      fail("connection closed: " + ec.message());
    }
    auto waiting = std::move(pending_);
    pending_.clear();
    for (auto& [id, p] : waiting)
      if (p.done) p.done(nullptr, nullptr);
    timer_.cancel();
    finishSculpting();
  }

  void onText(std::string_view text, double t) {
    const json m = json::parse(text, nullptr, false);
    if (m.is_discarded() || !m.is_object()) {
      ++stats_.anomalies["text message that is not a JSON object"];
      return;
    }
    const auto id = m.find("id");
    if (id == m.end()) {
      ++stats_.notifications[m.value("method", std::string("?"))];
      return;
    }
    const auto found = id->is_number_integer() ? pending_.find(id->get<long>()) : pending_.end();
    if (found == pending_.end()) {
      ++stats_.anomalies["response to no request"];
      return;
    }
    Pending p = std::move(found->second);
    pending_.erase(found);
    const double latency = t - p.sent;
    ++stats_.answered;
    if (const auto error = m.find("error"); error != m.end()) {
      ++stats_.errors[error->contains("code") ? (*error)["code"].dump() : "None"];
      if (stats_.errorSamples.size() < 5) stats_.errorSamples.push_back({{"method", p.method}, {"error", *error}});
      if (p.done) p.done(nullptr, &*error);
      return;
    }
    const json& result = m["result"];
    if (p.method == "stroke.dabs") {
      stats_.dabsLatency.push_back(latency);
      stats_.dabsSent.push_back(p.sent);
      stats_.sessionDabsLatency[session_.index].push_back(latency);
      const long applied = result.value("applied", 0L);
      stats_.dabsApplied += applied;
      if (applied > 0) {
        const long revision = result.value("revision", 0L);
        session_.lastRevision = std::max(session_.lastRevision, revision);
        session_.dabRevisions.insert(revision);
        if (lastDeltaRevision_ >= revision) {
          ++stats_.anomalies["delta before its response"];
        } else {
          awaitingDelta_.push_back({revision, p.sent, std::move(p.dabTimes)});
        }
      }
    } else {
      stats_.otherLatency[p.method].push_back(latency);
    }
    if (p.done) p.done(&result, nullptr);
  }

  void onBinary(std::span<const std::uint8_t> data, double t) {
    // protocol/PROTOCOL.md "Binary frames": "MZPN", u16 version 1, u16 kind, u32 request id,
    // u64 revision, u32 payload length, the payload.
    std::uint16_t version = 0, kind = 0;
    std::uint32_t requestId = 0, length = 0;
    std::uint64_t revision = 0;
    if (data.size() >= 24) {
      std::memcpy(&version, data.data() + 4, 2);
      std::memcpy(&kind, data.data() + 6, 2);
      std::memcpy(&requestId, data.data() + 8, 4);
      std::memcpy(&revision, data.data() + 12, 8);
      std::memcpy(&length, data.data() + 20, 4);
    }
    if (data.size() < 24 || std::memcmp(data.data(), "MZPN", 4) != 0 || version != 1 || kind < 1 || kind > 11 ||
        length != data.size() - 24) {
      ++stats_.anomalies["bad frame"];
      return;
    }
    const long rev = long(revision);
    if (creator_ && cfg_.dabSpacing > 0 && (kind == 1 || kind == 2))
      if (!session_.surface.apply(data.subspan(24), kind == 1)) ++stats_.anomalies["bad splat buffer"];
    if (kind == 1) {
      ++stats_.fullBuffers;
      lastDeltaRevision_ = std::max(lastDeltaRevision_, rev);
      return;
    }
    if (kind != 2 || requestId != 0) {
      ++stats_.anomalies["unexpected frame kind " + std::to_string(kind)];
      return;
    }
    ++stats_.deltas;
    stats_.deltaBytes += long(data.size());
    if (rev <= lastDeltaRevision_) ++stats_.anomalies["delta revision did not grow"];
    lastDeltaRevision_ = std::max(lastDeltaRevision_, rev);
    while (!awaitingDelta_.empty() && awaitingDelta_.front().revision <= rev) {
      const Awaiting& a = awaitingDelta_.front();
      stats_.deltaLatency.push_back(t - a.sent);
      stats_.sessionDeltaLatency[session_.index].push_back(t - a.sent);
      for (const double pointerAt : a.dabTimes) stats_.dabDeltaLatency.push_back(t - pointerAt);
      awaitingDelta_.pop_front();
    }
  }

  // ---- one stroke, as marzipan_load.py's sculpt_like_web_client makes it

  void beginStroke() {
    if (closed_ || now() >= end_) return finishSculpting();
    const std::string tool = kTools[std::size_t(index_ + strokeNumber_) % std::size(kTools)];
    ++strokeNumber_;
    // The browser picks a stroke's dabs on its splats as they were at the press.
    plan_.emplace(rng_, tool, cfg_.size, session_.surface.snapshot(), cfg_.dabSpacing);
    ++stats_.strokeTools[plan_->params.tool];
    stroke_ = nullptr;
    begun_ = failed_ = pointerDone_ = ending_ = false;
    inFlight_ = 0;
    queue_.clear();
    frame_ = 0;
    send("stroke.begin", paramsJson(plan_->params), [this](const json* result, const json*) {
      begun_ = true;
      if (result) {
        stroke_ = (*result)["stroke"];
      } else {
        failed_ = true;
        queue_.clear();
      }
      flush();
      maybeEndStroke();
    });
    due_ = now();
    tick();
  }

  void tick() {
    timer_.expires_at(at(due_));
    timer_.async_wait([this](beast::error_code ec) {
      if (ec) return;
      const double t = now();
      if (t >= end_) {
        pointerDone_ = true;
        return maybeEndStroke();
      }
      stats_.sendLag.push_back(t - due_);
      ++stats_.pointerEvents;
      const std::vector<WireDab> dabs = plan_->pointer(frame_);
      if (!failed_)
        for (const auto& d : dabs) queue_.push_back({dabJson(d), t});
      flush();
      due_ += 1 / kFrameHz;
      if (++frame_ < plan_->frames) return tick();
      pointerDone_ = true;
      maybeEndStroke();
    });
  }

  void flush() {
    while (!stroke_.is_null() && !queue_.empty() && inFlight_ < kMaxInFlight && !closed_) {
      const std::size_t n = std::min<std::size_t>(queue_.size(), kMaxDabs);
      json dabs = json::array();
      std::vector<double> times;
      for (std::size_t i = 0; i < n; ++i) {
        dabs.push_back(std::move(queue_[i].first));
        times.push_back(queue_[i].second);
      }
      queue_.erase(queue_.begin(), queue_.begin() + std::ptrdiff_t(n));
      ++inFlight_;
      stats_.dabsPerMessage.push_back(int(n));
      send("stroke.dabs", {{"stroke", stroke_}, {"dabs", std::move(dabs)}},
           [this](const json* result, const json*) {
             --inFlight_;
             if (!result) {
               failed_ = true;
               queue_.clear();
             }
             flush();
             maybeEndStroke();
           },
           std::move(times));
    }
  }

  // stroke.end once the pointer is up, stroke.begin answered and nothing waits or is in flight.
  void maybeEndStroke() {
    if (ending_ || !pointerDone_ || !begun_) return;
    if (closed_) return finishSculpting();
    if (!queue_.empty() || inFlight_ > 0) return;
    ending_ = true;
    if (!stroke_.is_null()) send("stroke.end", {{"stroke", stroke_}});
    timer_.expires_at(at(now() + kPauseS));
    timer_.async_wait([this](beast::error_code ec) {
      if (!ec) beginStroke();
    });
  }

  void finishSculpting() { sculptDone = true; }

  int index_;
  Session& session_;
  bool creator_;
  const Config& cfg_;
  Stats& stats_;
  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
  std::deque<std::string> outbox_;
  bool writing_ = false, closed_ = false;
  long nextId_ = 1;
  std::unordered_map<long, Pending> pending_;
  std::deque<Awaiting> awaitingDelta_;
  long lastDeltaRevision_ = 0;
  asio::steady_timer timer_;
  PyRandom rng_;
  double end_ = 0;
  // The stroke under way.
  int strokeNumber_ = 0, frame_ = 0, inFlight_ = 0;
  std::optional<WebClientStroke> plan_;
  json stroke_;  // its id once stroke.begin answered
  bool begun_ = false, failed_ = false, pointerDone_ = false, ending_ = false;
  double due_ = 0;
  std::vector<std::pair<json, double>> queue_;  // dabs waiting, with their pointer event's time
};

template <class T>
json keyed(const std::map<int, T>& m) {
  json j = json::object();
  for (const auto& [k, v] : m) j[std::to_string(k)] = v;
  return j;
}

int runClients(const Config& cfg) {
  asio::io_context io(1);
  Stats stats;
  std::vector<std::unique_ptr<Session>> sessions;
  for (std::size_t s = 0; s < cfg.sessions.size(); ++s) {
    sessions.push_back(std::make_unique<Session>());
    sessions.back()->index = int(s);
    sessions.back()->id = cfg.sessions[s];
    stats.sessionDabsLatency[int(s)];
    stats.sessionDeltaLatency[int(s)];
  }
  std::vector<std::unique_ptr<Client>> clients;
  const auto m = int(sessions.size());
  for (int c = 0; c < cfg.clients; ++c)
    clients.push_back(std::make_unique<Client>(io, c, *sessions[std::size_t(c % m)], c < m, cfg, stats));
  tcp::resolver resolver(io);
  const auto endpoints = resolver.resolve(cfg.host, cfg.port);
  for (auto& c : clients) c->enter(endpoints);

  auto runUntil = [&](double deadline, auto&& done) {
    while (!done() && now() < deadline) io.run_one_for(std::chrono::milliseconds(20));
    return done();
  };
  const auto firstError = [&]() -> std::string {
    for (const auto& c : clients)
      if (!c->setupError.empty()) return c->setupError;
    return {};
  };
  const bool ready = runUntil(now() + kSetupTimeoutS, [&] {
    return !firstError().empty() || std::all_of(clients.begin(), clients.end(), [](const auto& c) { return c->ready; });
  });
  if (!ready || !firstError().empty()) {
    std::cerr << "marzipan-load-client: setup failed: " << (firstError().empty() ? "timed out" : firstError()) << "\n";
    return 1;
  }
  std::cout << "ready" << std::endl;
  std::string word;
  double t0 = 0;
  if (!(std::cin >> word >> t0) || word != "start") {
    std::cerr << "marzipan-load-client: expected a line \"start T0\" on stdin\n";
    return 1;
  }
  const double end = t0 + cfg.duration;
  const double cpu0 = cpuSeconds();
  const json wait0 = runqueueWaitS();
  for (auto& c : clients) c->startSculpting(t0, end);
  // How late a 10 ms timer fires: whether this one thread keeps up.
  asio::steady_timer lagTimer(io);
  std::function<void()> lag = [&] {
    const double due = now() + 0.01;
    lagTimer.expires_at(at(due));
    lagTimer.async_wait([&, due](beast::error_code ec) {
      if (ec) return;
      stats.loopLag.push_back(now() - due);
      if (now() < end) lag();
    });
  };
  lag();
  while (!std::all_of(clients.begin(), clients.end(), [](const auto& c) { return c->sculptDone; })) io.run_one();

  json failures = json::array();
  runUntil(now() + kDrainTimeoutS,
           [&] { return std::none_of(clients.begin(), clients.end(), [](const auto& c) { return c->hasPending(); }); });
  long unanswered = 0;
  for (const auto& c : clients) unanswered += long(c->pendingCount());
  runUntil(now() + kDrainTimeoutS, [&] {
    return std::all_of(clients.begin(), clients.end(), [](const auto& c) {
      return c->closed() || c->lastDeltaRevision() >= c->session().lastRevision;
    });
  });
  for (const auto& c : clients)
    if (c->lastDeltaRevision() < c->session().lastRevision)
      failures.push_back("client " + std::to_string(c->index()) + ": last delta seen at revision " +
                         std::to_string(c->lastDeltaRevision()) + ", session " + std::to_string(c->session().index) +
                         " reached " + std::to_string(c->session().lastRevision));
  const double drained = now();
  const double cpu1 = cpuSeconds();
  const json wait1 = runqueueWaitS();
  const long answeredInRun = stats.answered;
  const auto sentInRun = stats.sent;

  // What the sessions hold after the run (volume and undo history), to explain the server's RSS.
  json sessionStats = json::array();
  int statsDue = 0;
  for (auto& c : clients) {
    if (!c->creator() || c->closed()) continue;
    ++statsDue;
    c->send("session.stats", json::object(), [&, index = c->session().index](const json* result, const json* error) {
      --statsDue;
      if (result) {
        sessionStats.push_back({{"revision", (*result)["revision"]}, {"memory_bytes", (*result)["memory_bytes"]},
                                {"history_bytes", (*result)["history_bytes"]}});
      } else {
        failures.push_back("session.stats of session " + std::to_string(index) + ": " +
                           (error ? error->dump() : std::string("closed")));
      }
    });
  }
  runUntil(now() + kSetupTimeoutS, [&] { return statsDue == 0; });
  stats.closing = true;
  int open = int(clients.size());
  for (auto& c : clients) c->close([&open] { --open; });
  runUntil(now() + kCloseTimeoutS, [&] { return open == 0; });

  long applications = 0;
  for (const auto& s : sessions) applications += long(s->dabRevisions.size());
  const json out{
      {"clients", cfg.clients},
      {"cpu_s", cpu1 - cpu0},
      {"wall_s", drained - t0},
      {"runqueue_wait_s", wait0.is_null() || wait1.is_null() ? json(nullptr) : json(wait1.get<double>() - wait0.get<double>())},
      {"drained_at", drained},
      {"sent", sentInRun},
      {"answered", answeredInRun},
      {"unanswered", unanswered},
      {"errors", stats.errors},
      {"error_samples", stats.errorSamples},
      {"notifications", stats.notifications},
      {"anomalies", stats.anomalies},
      {"unexpected_closes", stats.unexpectedCloses},
      {"failures", failures},
      {"dabs_latency", stats.dabsLatency},
      {"dabs_sent", stats.dabsSent},
      {"delta_latency", stats.deltaLatency},
      {"dab_delta_latency", stats.dabDeltaLatency},
      {"dabs_per_message", stats.dabsPerMessage},
      {"pointer_events", stats.pointerEvents},
      {"stroke_tools", stats.strokeTools},
      {"session_dabs_latency", keyed(stats.sessionDabsLatency)},
      {"session_delta_latency", keyed(stats.sessionDeltaLatency)},
      {"other_latency", stats.otherLatency},
      {"send_lag", stats.sendLag},
      {"loop_lag", stats.loopLag},
      {"dabs_applied", stats.dabsApplied},
      {"deltas", stats.deltas},
      {"delta_bytes", stats.deltaBytes},
      {"full_buffers", stats.fullBuffers},
      {"slow_client", nullptr},
      {"session_stats", sessionStats},
      {"dab_applications", applications},
  };
  std::cout << out.dump() << std::endl;
  return 0;
}

int plan(const std::string& file, int client, std::uint32_t seed, int size, int strokes, double dabSpacing) {
  std::ifstream in(file, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  SplatSurface surface;
  if (!surface.apply(bytes, true)) {
    std::cerr << "marzipan-load-client: " << file << " is not a splat buffer\n";
    return 1;
  }
  PyRandom rng(seed * 100003u + std::uint32_t(client));
  for (int s = 0; s < strokes; ++s) {
    WebClientStroke stroke(rng, kTools[std::size_t(client + s) % std::size(kTools)], size, surface.snapshot(), dabSpacing);
    json pointer = json::array();
    for (int k = 0; k < stroke.frames; ++k) {
      json dabs = json::array();
      for (const auto& d : stroke.pointer(k)) dabs.push_back(dabJson(d));
      pointer.push_back(std::move(dabs));
    }
    std::cout << json{{"params", paramsJson(stroke.params)}, {"frames", stroke.frames}, {"pointer", pointer}}.dump() << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace marzipan::load

int main(int argc, char** argv) {
  using namespace marzipan::load;
  Config cfg;
  std::string url, sessions, planFile;
  int client = 0, strokes = 4;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    auto value = [&] { return std::string(argv[++i]); };
    try {
      if (a == "--url" && hasValue) url = value();
      else if (a == "--clients" && hasValue) cfg.clients = std::stoi(value());
      else if (a == "--sessions" && hasValue) sessions = value();
      else if (a == "--size" && hasValue) cfg.size = std::stoi(value());
      else if (a == "--solid" && hasValue) cfg.solid = value();
      else if (a == "--seed" && hasValue) cfg.seed = std::uint32_t(std::stoul(value()));
      else if (a == "--duration" && hasValue) cfg.duration = std::stod(value());
      else if (a == "--dab-spacing" && hasValue) cfg.dabSpacing = std::stod(value());
      else if (a == "--plan" && hasValue) planFile = value();
      else if (a == "--client" && hasValue) client = std::stoi(value());
      else if (a == "--strokes" && hasValue) strokes = std::stoi(value());
      else {
        std::cerr << "marzipan-load-client: unknown or incomplete option " << a << " (see the head of load_client.cpp)\n";
        return 2;
      }
    } catch (const std::exception&) {
      std::cerr << "marzipan-load-client: bad value for " << a << "\n";
      return 2;
    }
  }
  if (!planFile.empty()) return plan(planFile, client, cfg.seed, cfg.size, strokes, cfg.dabSpacing);
  std::stringstream ids(sessions);
  for (std::string id; std::getline(ids, id, ',');)
    if (!id.empty()) cfg.sessions.push_back(id);
  // ws://HOST:PORT/PATH
  const auto scheme = url.find("ws://");
  const auto slash = url.find('/', 5);
  const auto colon = url.rfind(':', slash);
  if (scheme != 0 || slash == std::string::npos || colon == std::string::npos || colon < 5 || cfg.sessions.empty() ||
      cfg.clients < int(cfg.sessions.size()) || cfg.duration <= 0) {
    std::cerr << "marzipan-load-client: need --url ws://HOST:PORT/PATH, --sessions ID,... and --clients of at least one "
                 "per session\n";
    return 2;
  }
  cfg.host = url.substr(5, colon - 5);
  cfg.port = url.substr(colon + 1, slash - colon - 1);
  cfg.path = url.substr(slash);
  try {
    return runClients(cfg);
  } catch (const std::exception& e) {
    std::cerr << "marzipan-load-client: " << e.what() << "\n";
    return 1;
  }
}
