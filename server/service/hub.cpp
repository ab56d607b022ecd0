// The hub (see hub.hpp): the registry of live sessions, each connection's message queue, the
// methods of PROTOCOL.md, and the streaming of every change to every client.
//
// How a message travels: text()/binary() append it to the connection's queue; one pump task at
// a time takes the next message, parses it (protocol/cpp/rpc.hpp) and, for a session method,
// posts the work to the session's strand. Only when that work has sent its answer does the
// pump take the next message, so a connection's answers come in request order.
#include "service/hub.hpp"

#include <sys/random.h>

#include <atomic>
#include <cerrno>
#include <deque>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <variant>

#include <nlohmann/json.hpp>

#include "engine/decimate.hpp"
#include "engine/errors.hpp"
#include "engine/image_io.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/progress.hpp"
#include "engine/raycast.hpp"
#include "engine/solids.hpp"
#include "engine/thickness.hpp"
#include "engine/splats.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/splats.hpp"
#include "protocol/cpp/rpc.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"
#include "service/journal.hpp"
#include "service/session_storage.hpp"
#include "service/session_store.hpp"
#include "service/workers.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::Method;
using protocol::RpcCode;
using protocol::RpcException;
using protocol::ViewMode;
using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;
using SharedBytes = std::shared_ptr<const Bytes>;

namespace {

constexpr std::size_t kSessionIdChars = 22;  // 132 bits
constexpr std::size_t kTokenChars = 43;      // 258 bits
// op.progress notifications of one request come at most this often.
constexpr std::chrono::milliseconds kProgressInterval{250};
// Shutdown waits this long for running edits (long ones are cancelled), then as long again
// for the snapshots: with the network's grace period it exits within 10 s of SIGTERM.
constexpr std::chrono::milliseconds kShutdownWait{2'000};
// A request estimated above this many voxels (about 2 s here) runs as a Workers::LongTask.
constexpr double kLongOpVoxels = 2e7;

// Ids and secrets begin with a letter or digit so that no command line takes one for an option
// (`--join -x...`); the first character carries log2(62) bits instead of 6.
std::string randomText(std::size_t chars) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
  constexpr unsigned kAlphanumerics = 62;
  std::string s;
  s.reserve(chars);
  std::vector<unsigned char> bytes(chars);
  while (s.size() < chars) {
    std::size_t got = 0;
    while (got < chars) {
      const ssize_t n = ::getrandom(bytes.data() + got, chars - got, 0);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw std::runtime_error("no random bytes from the kernel");
      got += std::size_t(n);
    }
    for (std::size_t i = 0; i < chars && s.size() < chars; ++i) {
      const unsigned v = bytes[i] & 63u;
      if (s.empty() && v >= kAlphanumerics) continue;  // rejection keeps the first character uniform
      s.push_back(kAlphabet[v]);
    }
  }
  return s;
}

// Compares a secret with what a client sent in time that depends only on the secret's length.
bool sameSecret(const std::string& secret, const std::string& given) {
  unsigned diff = secret.size() != given.size() ? 1u : 0u;
  for (std::size_t i = 0; i < secret.size(); ++i)
    diff |= unsigned(std::uint8_t(secret[i]) ^ std::uint8_t(i < given.size() ? given[i] : 0));
  return diff == 0;
}

// {"jsonrpc":"2.0","id":...,"method":"op.cancel","params":{}} with room for a long string id.
constexpr std::size_t kMaxCancelBytes = 256;

json sizeJson(Int3 d) { return json::array({d.x, d.y, d.z}); }

// Grid edges the surface crosses (a sign change between two voxels of one brick; those across
// brick borders are left out, a few percent). Marching cubes makes one vertex per crossed edge
// and about two triangles per vertex, so this sizes a mesh before it is built.
std::size_t crossedEdges(const Volume& vol) {
  std::size_t edges = 0;
  vol.forEachPresentBrick([&](Int3, const Brick& b) {
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
          const int i = x + 8 * (y + 8 * z);
          const bool in = b.v[i] < 0;
          if (x < 7 && in != (b.v[i + 1] < 0)) ++edges;
          if (y < 7 && in != (b.v[i + 8] < 0)) ++edges;
          if (z < 7 && in != (b.v[i + 64] < 0)) ++edges;
        }
  });
  return edges;
}

// Bytes of a mesh file per crossed edge (one vertex, two triangles): STL 2 x 50; OBJ a "v"
// line and two "f" lines, PLY a vertex with its normal and two faces (140 and 55, measured on
// the 96^3 pig 2026-11-24; tests/service/test_hub.cpp holds each within 0.8-1.3 of the file);
// GLB a position and normal (24 bytes) and two triangles of 32-bit indices (24): 48.
std::size_t meshBytesPerEdge(const std::string& format) {
  return format == "stl" ? 100 : format == "obj" ? 140 : format == "glb" ? 48 : 55;
}

// The peer's address without its port ("1.2.3.4:5", "[::1]:5").
std::string addressOf(const std::string& peer) {
  if (!peer.empty() && peer.front() == '[') return peer.substr(0, peer.find(']') + 1);
  const std::size_t colon = peer.find(':');
  return colon != std::string::npos && colon == peer.rfind(':') ? peer.substr(0, colon) : peer;
}

SharedBytes makeFrame(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                      std::span<const std::uint8_t> payload) {
  return std::make_shared<const Bytes>(protocol::encodeFrame(kind, requestId, revision, payload));
}

struct Failure {
  RpcCode code;
  std::string message;
  json data;
};

// What any exception thrown while handling a request becomes. Validation errors keep their
// code; anything unexpected is an internal error whose text goes to the log only.
Failure failureOf(std::exception_ptr e, const std::function<void(const std::string&)>& log) {
  try {
    std::rethrow_exception(e);
  } catch (const RpcException& x) {
    return {x.code(), x.what(), x.data()};
  } catch (const protocol::OpError& x) {
    return {RpcCode::InvalidParams, x.message(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const ServiceError& x) {
    return {x.code(), x.message(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const EngineError& x) {
    return {RpcCode::EngineRefused, x.what(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const Cancelled&) {
    return {RpcCode::Cancelled, "the operation was cancelled (op.cancel or server shutdown); the session is unchanged",
            nullptr};
  } catch (const std::exception& x) {
    if (log) log(std::string("internal error: ") + x.what());
    return {RpcCode::Internal, "internal error; the session is unchanged", nullptr};
  } catch (...) {
    if (log) log("internal error");
    return {RpcCode::Internal, "internal error; the session is unchanged", nullptr};
  }
}

}  // namespace

struct LiveSession;

// Per-connection state. Fields are grouped by the one context that may touch them.
class HubClient {
 public:
  HubClient(std::shared_ptr<ClientLink> l, std::string p) : link(std::move(l)), peer(std::move(p)) {}

  const std::shared_ptr<ClientLink> link;
  const std::string peer;

  // Guarded by mutex: the queue of messages not yet handled.
  struct Incoming {
    std::variant<std::string, Bytes> message;
    Clock::time_point arrived;
  };
  std::mutex mutex;
  std::deque<Incoming> queue;
  bool busy = false;    // a pump task owns the connection
  bool closed = false;  // disconnected: drop everything
  std::size_t queuedBytes = 0;
  double tokens = 1e9;  // requests it may still send now (capped at the first refill)
  Clock::time_point refilled = Clock::now();
  std::shared_ptr<Progress> running;  // its long request in progress, for op.cancel

  // Pump only (one message at a time, so no lock is needed).
  std::shared_ptr<LiveSession> session;
  struct PendingLoad {
    json id;
    std::uint32_t frameId;
    std::uint64_t bytes;
    Clock::time_point arrived;
  };
  std::optional<PendingLoad> load;
  std::deque<Clock::time_point> creates;  // this connection's session.create in the last minute

  // Written on the session's strand, read anywhere: an editor of a session (may upload), a
  // member of one, and since when it is in none (for the lobby deadline).
  std::atomic<bool> editor{false}, member{false};
  std::atomic<Clock::rep> outsideSince{Clock::now().time_since_epoch().count()};

  // The session's strand only.
  int clientId = 0;
  bool readOnly = false;
  ViewMode mode = ViewMode::None;
  Camera camera;
  Shading shading = Shading::Lit;
  double thicknessMinVu = 1;
  StrokeId stroke = 0;
  std::uint64_t frameSeq = 0;     // bumped by every change or camera change
  bool rendering = false, renderAgain = false;
};

struct LiveSession : std::enable_shared_from_this<LiveSession> {
  LiveSession(std::string i, SessionSecrets s, Workers& w)
      : id(std::move(i)), secrets(std::move(s)), strand(std::make_shared<Strand>(w)) {}
  const std::string id;
  const SessionSecrets secrets;
  const std::shared_ptr<Strand> strand;

  // The strand only.
  std::unique_ptr<Session> session;
  std::unique_ptr<SessionLog> journal;  // with a persistent storage
  std::string failure;               // why the session could not be created
  // Its clients, weakly: a connection owns its HubClient, which holds its session, so ownership
  // runs one way (connection -> client -> session) and nothing needs breaking at shutdown.
  std::vector<std::weak_ptr<HubClient>> clients;
  // The clients still alive: all of them, except while the hub shuts down.
  std::vector<std::shared_ptr<HubClient>> members() const {
    std::vector<std::shared_ptr<HubClient>> out;
    out.reserve(clients.size());
    for (const auto& weak : clients)
      if (auto c = weak.lock()) out.push_back(std::move(c));
    return out;
  }
  int nextClient = 1;
  // The lease is released once (unload, shutdown); renewal, which runs off the strand so that a
  // long operation cannot let it expire, must not take it again after that.
  std::mutex leaseMutex;
  bool leaseReleased = false;
  // Written on the strand, also read under the hub's mutex (findOrLoad): atomic.
  std::atomic<bool> unloaded{false};
  bool syncScheduled = false;  // a --fsync-ms timer will sync the journal
  // Guarded by the hub's mutex: when the last client left (for the idle timeout).
  Clock::time_point emptySince = Clock::now();
  std::size_t clientCount = 0;
};

struct Hub::Impl : std::enable_shared_from_this<Hub::Impl> {
  explicit Impl(HubOptions o)
      : options(std::move(o)),
        owner(options.serverId.empty() ? randomText(16) : options.serverId),
        store(openStorage(options, owner)),
        workers(options.workers, options.events.log),
        pool(int(workers.threads())) {}

  // The storage the options name: theirs, files in the data directory, or none.
  static std::shared_ptr<SessionStorage> openStorage(const HubOptions& o, const std::string& owner) {
    if (o.storage) return o.storage;
    if (o.dataDir.empty()) return makeMemoryStorage();
    return std::make_shared<SessionStore>(o.dataDir, o.fsyncInterval, o.events.log, owner);
  }

  HubOptions options;
  const std::string owner;  // this server's name in leases
  const std::shared_ptr<SessionStorage> store;
  Workers workers;
  ThreadPool pool;  // for whole-volume kernels and renders; parallelFor serializes its callers
  mutable std::mutex mutex;  // guards sessions and stopping
  std::map<std::string, std::shared_ptr<LiveSession>> sessions;
  std::map<std::string, std::deque<Clock::time_point>> createsByAddress;  // in the last minute
  bool stopping = false;
  std::atomic<bool> idleCheckScheduled{false};
  std::atomic<bool> leaseRenewalScheduled{false};
  std::set<Progress*> runningOps;  // guarded by mutex: cancelled by shutdown
  // Guarded by mutex: sessions being recovered from the data directory, by id; a second join
  // waits for the first one's load instead of loading (and opening the journal) again.
  std::map<std::string, std::shared_future<std::shared_ptr<LiveSession>>> loading;

  const HubLimits& limits() const { return options.limits; }

  // --- long operations -----------------------------------------------------------------------
  // One long request's Progress (engine/progress.hpp): op.progress notifications to its
  // client, cancelled by that client's op.cancel or by shutdown. Registered from track() until
  // done() or its destruction (it is captured by the request's strand task).
  struct RunningOp {
    std::shared_ptr<Impl> hub;
    std::shared_ptr<HubClient> client;
    std::shared_ptr<Progress> progress;
    bool registered = true;
    void done() {
      if (!std::exchange(registered, false)) return;
      {
        const std::lock_guard lock(client->mutex);
        if (client->running == progress) client->running.reset();
      }
      const std::lock_guard lock(hub->mutex);
      hub->runningOps.erase(progress.get());
    }
    ~RunningOp() { done(); }
  };

  std::shared_ptr<RunningOp> track(const std::shared_ptr<HubClient>& c, const std::optional<json>& id) {
    auto progress = std::make_shared<Progress>(
        [link = c->link, request = id.value_or(json(nullptr))](double fraction) {
          link->sendText(protocol::notificationText("op.progress", {{"request", request}, {"fraction", fraction}}));
        },
        kProgressInterval);
    auto op = std::make_shared<RunningOp>(RunningOp{shared_from_this(), c, progress});
    {
      const std::lock_guard lock(c->mutex);
      c->running = progress;
    }
    const std::lock_guard lock(mutex);
    runningOps.insert(progress.get());
    if (stopping) progress->cancel();
    return op;
  }

  // Refuses a request whose estimated work is over max_op_voxels, before anything runs.
  void checkBudget(double voxels, const char* what) const {
    if (voxels <= limits().maxOpVoxels) return;
    char text[160];
    std::snprintf(text, sizeof text, "%s would process about %.3g voxels, over the server's max_op_voxels %.3g", what,
                  voxels, limits().maxOpVoxels);
    throw RpcException(RpcCode::LimitExceeded, std::string(text) + "; use fewer iterations, a smaller radius or fewer dabs",
                       {{"limit", "max_op_voxels"}, {"value", voxels}, {"max", limits().maxOpVoxels}});
  }

  // op.cancel overtakes the connection's queue, where the request it cancels holds the line:
  // handled here, on the caller's thread. False when text is not an op.cancel request.
  bool cancel(const std::shared_ptr<HubClient>& c, const std::string& text) {
    const protocol::ParsedRequest parsed = protocol::parseRequest(text);
    if (!parsed.request || parsed.request->method != Method::OpCancel) return false;
    const protocol::Request& req = *parsed.request;
    if (options.events.request) options.events.request("op.cancel");
    std::shared_ptr<Progress> running;
    {
      const std::lock_guard lock(c->mutex);
      if (c->closed) return true;
      running = c->running;
    }
    try {
      protocol::parseNoParams(req.params, Method::OpCancel);
    } catch (...) {
      sendError(*c, req.id, failureOf(std::current_exception(), options.events.log));
      return true;
    }
    if (running) running->cancel();
    sendResult(*c, req.id, {{"cancelled", running != nullptr}});
    return true;
  }

  void log(const std::string& line) const {
    if (options.events.log) options.events.log(line);
  }
  static void emit(const std::function<void(std::int64_t)>& f, std::int64_t v) {
    if (f) f(v);
  }

  // --- sending -----------------------------------------------------------------------------
  void sendResult(HubClient& c, const std::optional<json>& id, const json& result) {
    if (id) c.link->sendText(protocol::resultText(*id, result));
  }
  void sendError(HubClient& c, const json& id, bool notification, const Failure& f) {
    if (options.events.error) options.events.error(int(f.code));
    if (!notification) c.link->sendText(protocol::errorText(id, f.code, f.message, f.data));
  }
  void sendError(HubClient& c, const std::optional<json>& id, const Failure& f) {
    sendError(c, id ? *id : json(nullptr), !id.has_value(), f);
  }

  // --- the connection's queue ------------------------------------------------------------------
  void enqueue(const std::shared_ptr<HubClient>& c, HubClient::Incoming in) {
    bool start = false;
    const std::size_t size = std::visit([](const auto& m) { return m.size(); }, in.message);
    std::string refusal;
    {
      const std::lock_guard lock(c->mutex);
      if (c->closed) return;
      // Refill the connection's request budget (a token bucket: a burst of two seconds' worth).
      const double rate = double(limits().maxRequestsPerSecond);
      const auto now = Clock::now();
      c->tokens = std::min(2 * rate, c->tokens + rate * std::chrono::duration<double>(now - c->refilled).count());
      c->refilled = now;
      if (c->queue.size() >= limits().maxPendingMessages)
        refusal = "too many requests in flight on this connection (" + std::to_string(limits().maxPendingMessages) +
                  "); wait for answers before sending more";
      else if (c->tokens < 1)
        refusal = "more than " + std::to_string(limits().maxRequestsPerSecond) +
                  " requests per second on this connection; slow down";
      else if (c->queuedBytes + size > limits().maxBinaryBytes + limits().maxTextBytes)
        refusal = "too many bytes waiting on this connection; wait for answers before sending more";
      if (refusal.empty()) {
        c->tokens -= 1;
        c->queuedBytes += size;
        c->queue.push_back(std::move(in));
        if (!c->busy) start = c->busy = true;
      }
    }
    if (!refusal.empty()) {
      // Answered at once without queueing, after the lock: the link may send inline and, past
      // its queue bound, disconnect this client (which takes c->mutex). An upload cannot be
      // answered alone: its volume.load then fails with -32013.
      if (const auto* text = std::get_if<std::string>(&in.message)) {
        const protocol::ParsedRequest p = protocol::parseRequest(*text);
        const json id = p.request ? p.request->id.value_or(json(nullptr)) : p.error->id;
        const bool notification = p.request ? !p.request->id : p.error->notification;
        sendError(*c, id, notification, {RpcCode::Busy, refusal, {{"retry_after_ms", 100}}});
      }
      return;
    }
    if (start) workers.post([self = shared_from_this(), c] { self->pump(c); });
  }

  // Ends the handling of one message: the next one may start.
  void finish(const std::shared_ptr<HubClient>& c) {
    bool closed = false;
    {
      const std::lock_guard lock(c->mutex);
      if (!c->closed && c->queue.empty()) {
        c->busy = false;
        return;
      }
      closed = c->closed;
    }
    if (closed) return cleanup(c);
    workers.post([self = shared_from_this(), c] { self->pump(c); });
  }

  // After a disconnect, by whoever owns the connection then (busy stays set: nothing more runs).
  void cleanup(const std::shared_ptr<HubClient>& c) {
    c->load.reset();
    const std::shared_ptr<LiveSession> s = c->session;
    if (!s) return;
    s->strand->post([self = shared_from_this(), s, c] {
      if (!s->unloaded && s->session) self->leave(*s, *c);
      c->session.reset();
    });
  }

  void pump(const std::shared_ptr<HubClient>& c) {
    HubClient::Incoming in;
    {
      std::unique_lock lock(c->mutex);
      if (c->closed) {
        lock.unlock();
        return cleanup(c);
      }
      if (c->queue.empty()) {
        c->busy = false;
        return;
      }
      in = std::move(c->queue.front());
      c->queue.pop_front();
      c->queuedBytes -= std::visit([](const auto& m) { return m.size(); }, in.message);
    }
    try {
      if (auto* bytes = std::get_if<Bytes>(&in.message)) return handleBinary(c, std::move(*bytes));
      if (c->load) {
        const HubClient::PendingLoad load = *c->load;
        c->load.reset();
        sendError(*c, load.id, false,
                  {RpcCode::UploadMissing, "volume.load was not followed by its upload (a kind-9 binary frame with request id " +
                                               std::to_string(load.frameId) + ")", nullptr});
      }
      handleText(c, std::get<std::string>(in.message), in.arrived);
    } catch (...) {
      sendError(*c, json(nullptr), false, failureOf(std::current_exception(), options.events.log));
      finish(c);
    }
  }

  // --- dispatch ------------------------------------------------------------------------------
  void handleText(const std::shared_ptr<HubClient>& c, const std::string& text, Clock::time_point arrived) {
    const protocol::ParsedRequest parsed = protocol::parseRequest(text);
    if (!parsed.request) {
      const protocol::RpcError& e = *parsed.error;
      sendError(*c, e.id, e.notification, {e.code, e.message, e.data});
      return finish(c);
    }
    const protocol::Request& req = *parsed.request;
    if (options.events.request) options.events.request(protocol::nameOf(protocol::kMethodNames, req.method));
    // A binary-answered method sent as a notification has nowhere to put its answer.
    if (!req.id && protocol::needsFrameId(req.method)) return finish(c);
    bool refuse = false;
    {
      const std::lock_guard lock(mutex);
      refuse = stopping;
    }
    if (refuse) {
      sendError(*c, req.id, {RpcCode::Busy, "the server is shutting down", nullptr});
      return finish(c);
    }
    try {
      switch (req.method) {
        case Method::SessionCreate: return create(c, req, arrived);
        case Method::SessionJoin: return join(c, req, arrived);
        case Method::OpCancel:
          // Spelled so that Hub::text did not see it (escapes): nothing of this connection runs
          // while the pump handles a message.
          protocol::parseNoParams(req.params, req.method);
          sendResult(*c, req.id, {{"cancelled", false}});
          return finish(c);
        default: break;
      }
      if (!c->session) throw RpcException(RpcCode::NotInSession, "not in a session: session.create or session.join first");
      if (protocol::isEdit(req.method)) return edit(c, req, arrived);
      return read(c, req, arrived);
    } catch (...) {
      sendError(*c, req.id, failureOf(std::current_exception(), options.events.log));
      finish(c);
    }
  }

  void handleBinary(const std::shared_ptr<HubClient>& c, Bytes bytes) {
    const auto decoded = protocol::decodeFrameHeader(bytes, limits().maxBinaryBytes);
    if (!c->load || !decoded || decoded.frame->header.kind != protocol::FrameKind::VolumeUpload ||
        decoded.frame->header.requestId != c->load->frameId) {
      // An upload that answers no pending volume.load is dropped; a pending load whose next
      // message is another frame fails.
      if (c->load) {
        sendError(*c, c->load->id, false, {RpcCode::UploadMissing, "volume.load was not followed by its upload", nullptr});
        c->load.reset();
      }
      return finish(c);
    }
    const HubClient::PendingLoad load = *c->load;
    c->load.reset();
    const std::uint64_t got = decoded.frame->header.payloadLength;
    if (got != load.bytes) {
      sendError(*c, load.id, false,
                {RpcCode::UploadMissing,
                 "the upload holds " + std::to_string(got) + " bytes, volume.load announced " + std::to_string(load.bytes),
                 nullptr});
      return finish(c);
    }
    auto payload = std::make_shared<Bytes>(bytes.begin() + protocol::kFrameHeaderBytes, bytes.end());
    bytes.clear();
    onStrand(c, load.id, load.arrived, true, [this, c, payload](LiveSession& s, Reply& r) {
      Volume vol = ::marzipan::loadVolume(*payload);
      if (vol.memoryBytes() > limits().maxVolumeBytes)
        throw RpcException(RpcCode::LimitExceeded,
                           "the file's volume holds " + std::to_string(vol.memoryBytes()) + " bytes of bricks, over max_volume_bytes " +
                               std::to_string(limits().maxVolumeBytes),
                           {{"limit", "max_volume_bytes"}, {"value", vol.memoryBytes()}, {"max", limits().maxVolumeBytes}, {"field", "file"}});
      const Int3 d = s.session->volume().dims();
      if (vol.dims() != d)
        throw RpcException(RpcCode::EngineRefused,
                           "the file's grid is " + std::to_string(vol.dims().x) + "x" + std::to_string(vol.dims().y) + "x" +
                               std::to_string(vol.dims().z) + ", the session's " + std::to_string(d.x) + "x" +
                               std::to_string(d.y) + "x" + std::to_string(d.z),
                           {{"field", "file"}});
      // Another band width would be another grid: the load could not be one undoable step.
      if (vol.band() != s.session->volume().band())
        throw RpcException(RpcCode::EngineRefused,
                           "the file's band half-width is " + std::to_string(vol.band()) + " vu, the session's " +
                               std::to_string(s.session->volume().band()) + " vu; save it with the session's band",
                           {{"field", "file"}});
      ApplyResult a = s.session->load(std::move(vol));
      a.fullRefresh = true;
      r.record = [this, &s, payload, rev = a.revision] {
        return json{{"r", rev}, {"load", store->persistent() ? store->saveUpload(s.id, rev, *payload) : std::string()}};
      };
      r.result = {{"revision", a.revision}, {"digest", digestText(s.session->digest())}, {"roi", protocol::boxJson(a.roi)},
                  {"can_undo", s.session->canUndo()}, {"can_redo", s.session->canRedo()}};
      r.after = [this, &s, c, a] {
        // A snapshot now lets the next rotation remove this upload's file: without it every
        // load-R.mzv (up to max_binary_bytes each) stayed until snapshot_every records passed.
        if (s.journal) {
          try {
            rotate(s);
          } catch (const std::exception& e) {
            log("session " + s.id + ": snapshot after a load failed (" + e.what() + "); the journal goes on");
          }
        }
        changed(s, *c, "load", a.roi, a.bricks, true);
      };
    });
  }

  // --- running work on a session ---------------------------------------------------------------
  struct Reply {
    SharedBytes frame;  // sent before the result
    json result;
    std::function<void()> after;  // on the strand, after the response went out
    // The journal record(s) of a change (an object or an array of them), written before the
    // response; may write files of its own (an upload).
    std::function<json()> record;
  };

  // -32015, with data.owner when the storage knows which server owns the session (etcd).
  RpcException heldElsewhere(const std::string& id, const std::string& message) {
    const std::optional<std::string> owner = store->holder(id);
    return RpcException(RpcCode::HeldElsewhere, message, owner ? json{{"owner", *owner}} : json());
  }

  // On the strand: appends a change's records to the journal before it is acknowledged. When
  // that fails the session goes back to what the journal holds (the change is dropped) and the
  // request gets an error; if even that fails the session is closed, its acknowledged state
  // intact on disk.
  void persist(LiveSession& s, const std::function<json()>& makeRecords) {
    if (!s.journal) {
      // With a data directory a change is acknowledged only once journaled.
      if (store->persistent()) throw RpcException(RpcCode::Busy, "the server is shutting down; the change was not kept");
      return;
    }
    try {
      // Inside the try: making the records may write files (an undo's bricks, an upload).
      const json records = makeRecords();
      if (records.is_array())
        for (const json& r : records) s.journal->append(r);
      else
        s.journal->append(records);
    } catch (const OwnershipLost& e) {
      // Another server owns the session now: nothing here may be kept, and its clients find
      // it there when they join again.
      log("session " + s.id + ": " + e.what() + "; closing it here");
      s.journal.reset();
      closeBroken(s);
      throw heldElsewhere(s.id, "another server took over this session; the change was not kept. Join it again");
    } catch (const std::exception& e) {
      log("session " + s.id + ": " + e.what() + "; rolling back to the journal");
      s.journal.reset();
      try {
        Recovered rec = store->recover(s.id, limits().historyBytes, pool);
        s.session = std::move(rec.session);
        s.journal = std::move(rec.journal);
      } catch (const std::exception& again) {
        log("session " + s.id + ": cannot reopen its journal (" + again.what() + "); closing it");
        closeBroken(s);
      }
      for (const auto& c : s.members()) c->stroke = 0;
      throw RpcException(RpcCode::Internal, std::string("the change could not be stored (") + e.what() +
                                                "); it was not kept. The session is as it was");
    }
    if (s.journal->dirty()) scheduleSync(s);
    if (s.journal->records() >= options.snapshotEvery) {
      try {
        rotate(s);
      } catch (const OwnershipLost& e) {
        // The change was journaled while the lease was still this server's: acknowledged, but
        // the session goes.
        log("session " + s.id + ": " + e.what() + "; closing it here");
        s.journal.reset();
        closeBroken(s);
      } catch (const std::exception& e) {
        log("session " + s.id + ": snapshot failed (" + e.what() + "); the journal goes on");
      }
    }
  }

  // On the strand: a snapshot of s and a fresh journal that starts with the strokes still open,
  // so that their next dabs replay without the journal that began them.
  void rotate(LiveSession& s) {
    std::vector<json> head;
    for (const auto& [id, st] : s.session->openStrokeList()) head.push_back(strokeBeginRecord(id, st));
    s.journal = store->snapshot(s.id, s.session->volume(), head);
  }

  // On the strand: with --fsync-ms N, records that did not sync on append are synced by a timer
  // within N ms (an append syncs only when N ms passed since the last sync).
  void scheduleSync(LiveSession& s) {
    if (s.syncScheduled) return;
    s.syncScheduled = true;
    std::weak_ptr<LiveSession> weak;
    {
      const std::lock_guard lock(mutex);
      if (const auto it = sessions.find(s.id); it != sessions.end() && it->second.get() == &s) weak = it->second;
    }
    workers.postAfter(options.fsyncInterval, [self = shared_from_this(), weak] {
      const auto live = weak.lock();
      if (!live) return;
      live->strand->post([self, live] {
        live->syncScheduled = false;
        if (!live->journal || !live->journal->dirty()) return;
        try {
          live->journal->sync();
          if (self->options.events.journalSynced) self->options.events.journalSynced();
        } catch (const std::exception& e) {
          self->log("session " + live->id + ": " + e.what());
        }
      });
    });
  }


  void releaseLease(LiveSession& s) {
    const std::lock_guard lease(s.leaseMutex);
    if (std::exchange(s.leaseReleased, true)) return;
    store->release(s.id);
  }

  // On the strand: forgets a session whose in-memory state may be ahead of its journal.
  void closeBroken(LiveSession& s) {
    s.unloaded = true;
    {
      const std::lock_guard lock(mutex);
      if (const auto it = sessions.find(s.id); it != sessions.end() && it->second.get() == &s) sessions.erase(it);
    }
    emit(options.events.sessions, -1);
    emit(options.events.clients, -std::int64_t(s.clients.size()));
    for (const auto& c : s.members()) c->link->close(1011, "the session is no longer served here; join it again");
    s.clients.clear();
  }

  void scheduleLeaseRenewal() {
    if (!store->persistent() || leaseRenewalScheduled.exchange(true)) return;
    workers.postAfter(store->renewEvery(), [self = shared_from_this()] {
      self->leaseRenewalScheduled = false;
      std::vector<std::shared_ptr<LiveSession>> lives;
      {
        const std::lock_guard lock(self->mutex);
        for (const auto& [id, live] : self->sessions) lives.push_back(live);
      }
      for (const auto& renewed : lives) {
        bool held = false;
        try {
          const std::lock_guard lease(renewed->leaseMutex);
          if (renewed->leaseReleased) continue;  // unloaded meanwhile: renewing would take it back
          held = self->store->renew(renewed->id);
        } catch (const std::exception& e) {
          self->log("session " + renewed->id + ": renewing its lease failed: " + e.what());
          continue;  // a storage hiccup; the lease still has most of its time
        }
        if (!held) self->leaseLost(renewed->id);
      }
      if (!lives.empty()) self->scheduleLeaseRenewal();
    });
  }

  // Another server took session id (this one stalled past the expiry, or the storage says so):
  // two servers must never write one session, so this copy goes, unsaved; its clients are
  // closed and reconnect (through the balancer) to the new holder.
  void leaseLost(const std::string& id) {
    std::shared_ptr<LiveSession> live;
    {
      const std::lock_guard lock(mutex);
      if (const auto it = sessions.find(id); it != sessions.end()) live = it->second;
    }
    if (!live) return;
    log("session " + id + ": another server took its lease; closing it here");
    live->strand->post([self = shared_from_this(), live] {
      if (live->unloaded) return;
      live->journal.reset();
      self->closeBroken(*live);
    });
  }

  // Runs fn on c's session strand, answers, then lets the connection's next message start.
  void onStrand(const std::shared_ptr<HubClient>& c, const std::optional<json>& id, Clock::time_point arrived, bool isEdit,
                std::function<void(LiveSession&, Reply&)> fn) {
    onStrand(c, c->session, id, arrived, isEdit, std::move(fn));
  }
  // The same on the strand of s, which c need not be a client of (yet): session.create/join.
  void onStrand(const std::shared_ptr<HubClient>& c, std::shared_ptr<LiveSession> s, const std::optional<json>& id,
                Clock::time_point arrived, bool isEdit, std::function<void(LiveSession&, Reply&)> fn) {
    s->strand->post([self = shared_from_this(), c, s, id, arrived, isEdit, fn = std::move(fn)] {
      Reply r;
      try {
        if (s->unloaded || !s->session) {
          if (c->session == s) c->session.reset();
          if (!s->failure.empty()) throw RpcException(RpcCode::Internal, s->failure);
          throw RpcException(RpcCode::NotInSession, "the session was closed; join it again");
        }
        fn(*s, r);
        if (r.record) self->persist(*s, r.record);
        if (r.frame) c->link->sendBinary(r.frame, false);
        self->sendResult(*c, id, r.result);
        if (isEdit && self->options.events.editLatency)
          self->options.events.editLatency(std::chrono::duration<double>(Clock::now() - arrived).count());
        if (r.after) r.after();
      } catch (...) {
        self->sendError(*c, id, failureOf(std::current_exception(), self->options.events.log));
      }
      self->finish(c);
    });
  }

  // Takes a snapshot on the strand, then runs fn on the workers off the strand (renders,
  // exports), answers and lets the connection go on.
  // atStrand, when given, starts the reply on the strand with what needs the live session.
  void offStrand(const std::shared_ptr<HubClient>& c, const std::optional<json>& id,
                 std::function<void(const Volume&, std::uint64_t revision, Reply&)> fn,
                 std::function<void(LiveSession&, Reply&)> atStrand = {}) {
    std::shared_ptr<LiveSession> s = c->session;
    s->strand->post([self = shared_from_this(), c, s, id, fn = std::move(fn), atStrand = std::move(atStrand)]() mutable {
      if (s->unloaded || !s->session) {
        self->sendError(*c, id, {RpcCode::NotInSession, "the session was closed", nullptr});
        return self->finish(c);
      }
      auto snapshot = std::make_shared<Volume>(s->session->snapshot());
      const std::uint64_t revision = s->session->revision();
      auto started = std::make_shared<Reply>();
      if (atStrand) atStrand(*s, *started);
      self->workers.post([self, c, id, snapshot, revision, fn = std::move(fn), started] {
        Reply& r = *started;
        try {
          fn(*snapshot, revision, r);
          if (r.frame) c->link->sendBinary(r.frame, false);
          self->sendResult(*c, id, r.result);
        } catch (...) {
          self->sendError(*c, id, failureOf(std::current_exception(), self->options.events.log));
        }
        self->finish(c);
      });
    });
  }

  void checkProtocol(const std::optional<int>& major) {
    if (major && *major != protocol::kProtocolMajor)
      throw RpcException(RpcCode::UnsupportedProtocol,
                         "protocol major version " + std::to_string(*major) + " is not supported; this server speaks " +
                             std::to_string(protocol::kProtocolMajor) + "." + std::to_string(protocol::kProtocolMinor),
                         {{"field", "protocol"},
                          {"supported", {{"major", protocol::kProtocolMajor}, {"minor", protocol::kProtocolMinor}}}});
  }

  RpcException sessionsFull() const {
    return RpcException(RpcCode::LimitExceeded,
                        "the server holds its " + std::to_string(limits().maxSessions) + " sessions; try later",
                        {{"limit", "max_sessions"}, {"max", limits().maxSessions}});
  }

  json limitsJson() const {
    const HubLimits& l = limits();
    return {{"max_text_bytes", l.maxTextBytes},
            {"max_binary_bytes", l.maxBinaryBytes},
            {"max_grid_side", l.maxGridSide},
            {"max_sessions", l.maxSessions},
            {"max_clients_per_session", l.maxClientsPerSession},
            {"max_dabs", l.maxDabs},
            {"max_frame_side", l.maxFrameSide},
            {"history_bytes", l.historyBytes},
            {"idle_session_seconds", l.idleSession.count()},
            {"ping_seconds", l.ping.count()},
            {"max_queue_bytes", l.maxQueuedBytes},
            {"max_connections", l.maxConnections},
            {"max_connections_per_address", l.maxConnectionsPerAddress},
            {"lobby_seconds", l.lobby.count()},
            {"max_volume_bytes", l.maxVolumeBytes},
            {"max_output_bytes", l.maxOutputBytes},
            {"max_creates_per_minute", l.maxCreatesPerMinute},
            {"max_creates_per_address_per_minute", l.maxCreatesPerAddressPerMinute},
            {"max_session_age_days", l.maxSessionAge.count() / 24},
            {"max_op_voxels", l.maxOpVoxels}};
  }

  static json clientsJson(const LiveSession& s) {
    json list = json::array();
    for (const auto& c : s.members()) list.push_back({{"client", c->clientId}, {"read_only", c->readOnly}});
    return list;
  }

  json sessionInfo(const LiveSession& s, const HubClient& c) const {
    const Session& ss = *s.session;
    return {{"session", s.id},
            {"client", c.clientId},
            {"size", sizeJson(ss.volume().dims())},
            {"revision", ss.revision()},
            {"digest", digestText(ss.digest())},
            {"protocol", {{"major", protocol::kProtocolMajor}, {"minor", protocol::kProtocolMinor}}},
            {"limits", limitsJson()},
            {"can_undo", ss.canUndo()},
            {"can_redo", ss.canRedo()},
            {"read_only", c.readOnly},
            {"clients", clientsJson(s)}};
  }

  // On the strand: c becomes a client of s and gets the full buffer after its response.
  void admit(LiveSession& s, const std::shared_ptr<HubClient>& c, bool readOnly, ViewMode view, Reply& r) {
    if (s.clients.size() >= limits().maxClientsPerSession)
      throw RpcException(RpcCode::SessionFull,
                         "the session has its " + std::to_string(limits().maxClientsPerSession) + " clients",
                         {{"limit", "max_clients_per_session"}, {"max", limits().maxClientsPerSession}});
    c->clientId = s.nextClient++;
    c->readOnly = readOnly;
    c->mode = view;
    c->stroke = 0;
    c->member = true;
    c->editor = !readOnly;
    c->rendering = c->renderAgain = false;  // a render of an earlier membership no longer counts
    s.clients.push_back(c);
    {
      const std::lock_guard lock(mutex);
      ++s.clientCount;
    }
    emit(options.events.clients, 1);
    r.result = sessionInfo(s, *c);
    auto self = shared_from_this();
    r.after = [self, &s, c] {
      if (c->mode == ViewMode::Splats) self->sendFullSplats(s, *c, 0);
      self->broadcastClients(s, c.get());
    };
  }

  void broadcastClients(LiveSession& s, const HubClient* except) {
    const std::string text = protocol::notificationText("session.clients", {{"clients", clientsJson(s)}});
    for (const auto& other : s.members())
      if (other.get() != except) other->link->sendText(text);
  }

  // On the strand: c leaves s (ending its stroke); the others hear of it.
  void leave(LiveSession& s, HubClient& c) {
    const auto it = std::find_if(s.clients.begin(), s.clients.end(), [&](const auto& p) { return p.lock().get() == &c; });
    if (it == s.clients.end()) return;
    if (c.stroke) {
      try {
        s.session->endStroke(c.stroke);
        if (s.journal) s.journal->append({{"stroke_end", c.stroke}});
      } catch (const std::exception& e) {
        // Already closed by the session (a reload), or not journaled: replay then ends the
        // stroke at the end of the journal, which folds the same dabs into the same step.
        log("session " + s.id + ": ending client " + std::to_string(c.clientId) + "'s stroke: " + e.what());
      }
      c.stroke = 0;
    }
    s.clients.erase(it);
    c.mode = ViewMode::None;
    c.editor = false;
    c.member = false;
    c.outsideSince = Clock::now().time_since_epoch().count();
    {
      const std::lock_guard lock(mutex);
      --s.clientCount;
      if (s.clientCount == 0) s.emptySince = Clock::now();
    }
    emit(options.events.clients, -1);
    log("session " + s.id + ": client " + std::to_string(c.clientId) + " (" + c.peer + ") left, " +
        std::to_string(s.clients.size()) + " remain");
    broadcastClients(s, nullptr);
    // A session nobody changed holds nothing worth keeping in memory: its slot goes at once.
    if (s.clients.empty() && s.session->revision() == 0) return unload(s, "left unchanged");
    scheduleIdleCheck();
  }

  // --- session.create / session.join ------------------------------------------------------------
  void create(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived) {
    const protocol::CreateParams p = protocol::parseCreateParams(req.params);
    checkProtocol(p.protocol);
    if (c->session) throw RpcException(RpcCode::AlreadyInSession, "already in a session: session.leave first");
    for (int a = 0; a < 3; ++a)
      if (p.size[a] > limits().maxGridSide)
        throw RpcException(RpcCode::LimitExceeded,
                           "\"size\"[" + std::to_string(a) + "] " + std::to_string(p.size[a]) +
                               " is over the server's max_grid_side " + std::to_string(limits().maxGridSide),
                           {{"limit", "max_grid_side"}, {"value", p.size[a]}, {"max", limits().maxGridSide}, {"field", "size"}});
    checkCreateRate(*c);
    const std::string id = p.session.value_or(randomText(kSessionIdChars));
    auto s = std::make_shared<LiveSession>(id, SessionSecrets{randomText(kTokenChars), randomText(kTokenChars)}, workers);
    {
      const std::lock_guard lock(mutex);
      if (sessions.count(id) || store->exists(id))
        throw RpcException(RpcCode::SessionExists, "a session with id \"" + id + "\" exists already; propose another",
                           {{"field", "session"}});
      if (sessions.size() >= limits().maxSessions) throw sessionsFull();
      sessions[id] = s;
    }
    emit(options.events.sessions, 1);
    const ViewMode view = p.view;
    const Int3 dims = p.size;
    const SolidKind solid = p.solid;
    auto self = shared_from_this();
    // The volume is built on the strand, before anything else can reach the new session.
    s->strand->post([self, s, dims, solid] {
      try {
        s->session = std::make_unique<Session>(makeSolid(solid, dims, Volume::kDefaultBand, self->pool),
                                               self->limits().historyBytes);
        if (self->store->persistent()) {
          if (!self->store->acquire(s->id))
            throw self->heldElsewhere(s->id, "another server holds this session id");
          s->journal = self->store->create(s->id, s->secrets, s->session->volume());
          self->scheduleLeaseRenewal();
        }
      } catch (const std::exception& e) {
        self->log("session " + s->id + ": creating it failed: " + e.what());
        s->failure = std::string("the session could not be created: ") + e.what();
        s->session.reset();
        s->unloaded = true;
        {
          const std::lock_guard lock(self->mutex);
          self->sessions.erase(s->id);
        }
        emit(self->options.events.sessions, -1);
      }
    });
    // c->session is set only once admitted: a refused create leaves the connection as it was.
    onStrand(c, s, req.id, arrived, false, [self, c, s, view, dims, solid](LiveSession& ls, Reply& r) {
      self->admit(ls, c, false, view, r);
      c->session = s;
      r.result["token"] = ls.secrets.token;
      r.result["view_token"] = ls.secrets.viewToken;
      self->log("session " + ls.id + ": created (" + solidKindName(solid) + " " + std::to_string(dims.x) + "x" +
                std::to_string(dims.y) + "x" + std::to_string(dims.z) + ") by " + c->peer);
    });
  }

  // Counts a session.create of c against the per-minute bounds, or refuses it (-32004).
  void checkCreateRate(HubClient& c) {
    const auto now = Clock::now();
    const auto minuteAgo = now - std::chrono::minutes(1);
    const auto refuse = [](const char* limit, std::size_t max, const std::string& who) {
      return RpcException(RpcCode::LimitExceeded,
                          std::to_string(max) + " sessions were created " + who + " in the last minute; try later",
                          {{"limit", limit}, {"max", max}, {"retry_after_ms", 60'000}});
    };
    while (!c.creates.empty() && c.creates.front() < minuteAgo) c.creates.pop_front();
    if (c.creates.size() >= limits().maxCreatesPerMinute)
      throw refuse("max_creates_per_minute", limits().maxCreatesPerMinute, "on this connection");
    {
      const std::lock_guard lock(mutex);
      for (auto it = createsByAddress.begin(); it != createsByAddress.end();) {
        while (!it->second.empty() && it->second.front() < minuteAgo) it->second.pop_front();
        it = it->second.empty() ? createsByAddress.erase(it) : std::next(it);
      }
      auto& mine = createsByAddress[addressOf(c.peer)];
      if (mine.size() >= limits().maxCreatesPerAddressPerMinute) {
        if (mine.empty()) createsByAddress.erase(addressOf(c.peer));
        throw refuse("max_creates_per_address_per_minute", limits().maxCreatesPerAddressPerMinute, "from this address");
      }
      mine.push_back(now);
    }
    c.creates.push_back(now);
  }

  void join(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived) {
    const protocol::JoinParams p = protocol::parseJoinParams(req.params);
    checkProtocol(p.protocol);
    if (c->session) throw RpcException(RpcCode::AlreadyInSession, "already in a session: session.leave first");
    std::shared_ptr<LiveSession> s = findOrLoad(p.session, p.token);
    bool readOnly = false;
    if (sameSecret(s->secrets.token, p.token)) readOnly = false;
    else if (sameSecret(s->secrets.viewToken, p.token)) readOnly = true;
    else throw RpcException(RpcCode::BadToken, "the token opens neither edit nor view rights of this session", {{"field", "token"}});
    const ViewMode view = p.view;
    auto self = shared_from_this();
    // c->session is set only once admitted: a refused join (a full session) grants nothing.
    onStrand(c, s, req.id, arrived, false, [self, c, s, view, readOnly](LiveSession& ls, Reply& r) {
      self->admit(ls, c, readOnly, view, r);
      // An editor may share a view link; a view client learns nothing more than it had.
      if (!readOnly) r.result["view_token"] = ls.secrets.viewToken;
      c->session = s;
      self->log("session " + ls.id + ": client " + std::to_string(c->clientId) + " (" + c->peer + ") joined" +
                (readOnly ? " read-only" : "") + ", " + std::to_string(ls.clients.size()) + " in all");
    });
  }

  // The live session of this id, loading it from the data directory when it sleeps there. One
  // loader per id: concurrent joins wait for it. max_sessions is checked before any work.
  std::shared_ptr<LiveSession> findOrLoad(const std::string& id, const std::string& token) {
    std::shared_future<std::shared_ptr<LiveSession>> pending;
    std::promise<std::shared_ptr<LiveSession>> mine;
    {
      const std::lock_guard lock(mutex);
      if (const auto it = sessions.find(id); it != sessions.end() && !it->second->unloaded) return it->second;
      if (const auto it = loading.find(id); it != loading.end()) pending = it->second;
      else if (sessions.size() + loading.size() >= limits().maxSessions) throw sessionsFull();
      else loading.emplace(id, mine.get_future().share());
    }
    if (pending.valid()) {
      // The caller checks this client's token against the loaded session's secrets. A load
      // that failed (perhaps for the other joiner's token) is tried again with this one.
      try {
        return pending.get();
      } catch (...) {
        return findOrLoad(id, token);
      }
    }
    const auto settle = [&] {
      const std::lock_guard lock(mutex);
      loading.erase(id);
    };
    try {
      std::shared_ptr<LiveSession> s = load(id, token);
      settle();
      mine.set_value(s);
      return s;
    } catch (...) {
      settle();
      mine.set_exception(std::current_exception());
      throw;
    }
  }

  std::shared_ptr<LiveSession> load(const std::string& id, const std::string& token) {
    const std::optional<SessionSecrets> secrets = store->secrets(id);
    if (!secrets) throw RpcException(RpcCode::NoSuchSession, "no session with id \"" + id + "\"", {{"field", "session"}});
    if (!sameSecret(secrets->token, token) && !sameSecret(secrets->viewToken, token))
      throw RpcException(RpcCode::BadToken, "the token opens neither edit nor view rights of this session", {{"field", "token"}});
    if (!store->acquire(id))
      throw heldElsewhere(id, "another server has session \"" + id + "\" loaded; connect with /ws?session=" + id +
                                  " through the load balancer, or to the server data.owner names");
    Recovered rec;
    try {
      rec = store->recover(id, limits().historyBytes, pool);
    } catch (...) {
      store->release(id);
      throw;
    }
    auto s = std::make_shared<LiveSession>(id, *secrets, workers);
    s->session = std::move(rec.session);
    s->journal = std::move(rec.journal);
    scheduleLeaseRenewal();
    {
      const std::lock_guard lock(mutex);
      // Its slot was counted in `loading` when the load began.
      sessions[id] = s;
    }
    emit(options.events.sessions, 1);
    log("session " + id + ": loaded from " + store->where() + " at revision " +
        std::to_string(s->session->revision()) + " (" + std::to_string(rec.replayed) + " journal records replayed)");
    return s;
  }

  // --- edits ---------------------------------------------------------------------------------------
  void edit(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived);
  void read(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived);

  // On the strand, after a change: the notification, then each client's delta or frame.
  void changed(LiveSession& s, const HubClient& by, std::string_view cause, const Box& roi, const std::vector<Int3>& bricks,
               bool full) {
    const Session& ss = *s.session;
    const std::string text = protocol::notificationText(
        "session.changed", {{"revision", ss.revision()},
                            {"by", by.clientId},
                            {"cause", cause},
                            {"roi", protocol::boxJson(roi)},
                            {"digest", digestText(ss.digest())},
                            {"can_undo", ss.canUndo()},
                            {"can_redo", ss.canRedo()}});
    const auto members = s.members();
    for (const auto& c : members) c->link->sendText(text);
    SharedBytes delta;
    for (const auto& c : members) {
      if (c->mode == ViewMode::Splats) {
        if (full) {
          sendFullSplats(s, *c, 0);
          continue;
        }
        if (!delta) {
          const Bytes payload = encodeSplats(extractSplats(ss.volume(), bricks));
          delta = makeFrame(protocol::FrameKind::SplatsDelta, 0, ss.revision(), payload);
        }
        c->link->sendBinary(delta, false);
      } else if (c->mode == ViewMode::Frames) {
        requestFrame(s, c);
      }
    }
  }

  SharedBytes fullSplatsFrame(const Volume& vol, std::uint32_t requestId, std::uint64_t revision, std::size_t* bricks,
                              std::size_t* points) {
    const std::vector<BrickSplats> all = extractAllSplats(vol, pool);
    if (bricks) *bricks = all.size();
    if (points) {
      *points = 0;
      for (const BrickSplats& b : all) *points += b.points.size();
    }
    return makeFrame(protocol::FrameKind::SplatsFull, requestId, revision, encodeSplats(all));
  }

  void sendFullSplats(LiveSession& s, HubClient& c, std::uint32_t requestId) {
    c.link->sendBinary(fullSplatsFrame(s.session->volume(), requestId, s.session->revision(), nullptr, nullptr), false);
  }

  // On the strand: a pushed frame for a frames-mode client, latest wins; a still one follows
  // once nothing changed for stillDelay.
  void requestFrame(LiveSession& s, const std::shared_ptr<HubClient>& c) {
    ++c->frameSeq;
    if (c->rendering) {
      c->renderAgain = true;
      return;
    }
    startRender(s, c, false);
  }

  // On s's strand: c is still the client `clientId` of s (it did not leave, or leave and join
  // again), so its view state belongs to this strand.
  static bool sameClient(const LiveSession& s, const HubClient& c, int clientId) {
    return std::any_of(s.clients.begin(), s.clients.end(), [&](const auto& p) { return p.lock().get() == &c; }) &&
           c.clientId == clientId;
  }

  void startRender(LiveSession& s, const std::shared_ptr<HubClient>& c, bool still) {
    c->rendering = true;
    auto snapshot = std::make_shared<Volume>(s.session->snapshot());
    const std::uint64_t revision = s.session->revision(), seq = c->frameSeq;
    const Camera camera = c->camera;
    const Shading shading = c->shading;
    const double minVu = c->thicknessMinVu;
    const int quality = still ? options.stillQuality : options.interactiveQuality;
    // The client may have left s (and joined another session, whose strand owns its view state
    // then) by the time the render is done: s's strand touches c only while c is still the
    // same client of s (c->session belongs to the connection's pump, not to this strand).
    std::weak_ptr<LiveSession> weak = s.weak_from_this();
    const int clientId = c->clientId;
    workers.post([self = shared_from_this(), weak, c, clientId, snapshot, revision, seq, camera, shading, minVu, quality, still] {
      try {
        const Frame f =
            render(*snapshot, camera, shading, self->pool, still ? FrameQuality::Still : FrameQuality::Interactive, minVu);
        const Bytes jpeg = encodeJpeg(f.rgb, f.width, f.height, quality);
        c->link->sendBinary(makeFrame(protocol::FrameKind::FrameJpeg, 0, revision, jpeg), true);
      } catch (const std::exception& e) {
        self->log(std::string("frame render failed: ") + e.what());
      }
      const auto live = weak.lock();
      if (!live) return;
      live->strand->post([self, s = live, c, clientId, seq, still] {
        if (!self->sameClient(*s, *c, clientId)) return;
        c->rendering = false;
        if (c->mode != ViewMode::Frames) return;
        if (c->renderAgain) {
          c->renderAgain = false;
          return self->startRender(*s, c, false);
        }
        if (still) return;
        self->workers.postAfter(self->options.stillDelay, [self, s, c, clientId, seq] {
          s->strand->post([self, s, c, clientId, seq] {
            if (self->sameClient(*s, *c, clientId) && c->mode == ViewMode::Frames && !c->rendering && c->frameSeq == seq)
              self->startRender(*s, c, true);
          });
        });
      });
    });
  }

  // Closes c once it has been in no session for the lobby time; re-arms itself while it is in
  // one or has not been out that long.
  void scheduleLobbyCheck(const std::weak_ptr<HubClient>& weak, std::chrono::milliseconds delay) {
    workers.postAfter(delay, [self = shared_from_this(), weak] {
      const auto c = weak.lock();
      if (!c) return;
      {
        const std::lock_guard lock(c->mutex);
        if (c->closed) return;
      }
      const auto lobby = std::chrono::duration_cast<std::chrono::milliseconds>(self->limits().lobby);
      const auto out = Clock::now() - Clock::time_point(Clock::duration(c->outsideSince.load()));
      if (c->member || out < lobby) {
        const auto left = c->member ? lobby : lobby - std::chrono::duration_cast<std::chrono::milliseconds>(out);
        return self->scheduleLobbyCheck(weak, std::max(left, std::chrono::milliseconds(10)));
      }
      c->link->close(1008, "no session joined within " + std::to_string(self->limits().lobby.count()) + " s");
    });
  }

  // Deletes sessions at rest untouched for max_session_age, now and then every hour.
  void sweepOldSessions(std::chrono::milliseconds delay) {
    if (!store->persistent()) return;
    workers.postAfter(delay, [self = shared_from_this()] {
      try {
        const auto removed = self->store->removeUntouched(
            std::chrono::duration_cast<std::chrono::seconds>(self->limits().maxSessionAge),
            [&](const std::string& id) {
              const std::lock_guard lock(self->mutex);
              return self->sessions.count(id) > 0;
            });
        for (const std::string& id : removed)
          self->log("session " + id + ": untouched for " + std::to_string(self->limits().maxSessionAge.count() / 24) +
                    " days, deleted");
      } catch (const std::exception& e) {
        self->log(std::string("sweeping old sessions failed: ") + e.what());
      }
      self->sweepOldSessions(std::chrono::hours(1));
    });
  }

  // --- idle sessions ---------------------------------------------------------------------------------
  void scheduleIdleCheck() {
    if (idleCheckScheduled.exchange(true)) return;
    const auto delay = std::max<std::chrono::milliseconds>(std::chrono::milliseconds(100),
                                                          std::chrono::duration_cast<std::chrono::milliseconds>(limits().idleSession) / 4);
    workers.postAfter(delay, [self = shared_from_this()] {
      self->idleCheckScheduled = false;
      self->unloadIdle();
    });
  }

  void unloadIdle() {
    std::vector<std::shared_ptr<LiveSession>> idle;
    bool more = false;
    {
      const std::lock_guard lock(mutex);
      for (const auto& [id, s] : sessions) {
        if (s->clientCount != 0) continue;
        if (Clock::now() - s->emptySince >= limits().idleSession) idle.push_back(s);
        else more = true;
      }
    }
    for (const auto& s : idle) s->strand->post([self = shared_from_this(), s] { self->unload(*s, "idle"); });
    if (more) scheduleIdleCheck();
  }

  // On the strand: saves (when there is a data directory) and forgets a session without clients.
  void unload(LiveSession& s, const char* why) {
    if (s.unloaded || !s.clients.empty() || !s.session) return;
    if (store->persistent() && s.journal) {
      try {
        s.journal = store->snapshot(s.id, s.session->volume());
        s.journal.reset();
      } catch (const std::exception& e) {
        // The journal holds every acknowledged change: the session is safe without the snapshot.
        log("session " + s.id + ": snapshot at unload failed: " + e.what());
      }
      releaseLease(s);
    }
    s.journal.reset();
    s.unloaded = true;
    {
      const std::lock_guard lock(mutex);
      if (const auto it = sessions.find(s.id); it != sessions.end() && it->second.get() == &s) sessions.erase(it);
    }
    emit(options.events.sessions, -1);
    log("session " + s.id + ": " + why + ", " + (store->persistent() ? "saved and unloaded" : "discarded (no --data-dir)"));
    s.session.reset();
  }
};

void Hub::Impl::edit(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived) {
  // Params are checked before the read-only test so that a malformed request says what is wrong.
  const HubLimits& l = limits();
  auto self = shared_from_this();
  const auto refuseReadOnly = [c](LiveSession&) {
    if (c->readOnly) throw RpcException(RpcCode::ReadOnly, "this client joined with the view token: edits are refused");
  };
  switch (req.method) {
    case Method::ToolApply: {
      const protocol::ToolApplyParams p = protocol::parseToolApplyParams(req.params);
      const auto running = track(c, req.id);
      return onStrand(c, req.id, arrived, true, [self, c, p, refuseReadOnly, running](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        const OpCost cost = estimateCost(s.session->volume(), p.op);
        self->checkBudget(cost.voxels, "this tool");
        running->progress->setTotal(cost.passes);
        protocol::Op op = p.op;
        std::optional<Vec3> hit;
        if (p.ray) {
          hit = s.session->pick(Ray{p.ray->origin, p.ray->direction});
          if (!hit) {
            r.result = {{"revision", s.session->revision()}, {"roi", nullptr}, {"hit", nullptr}};
            return;
          }
          if (auto* b = std::get_if<protocol::BrushOp>(&op)) b->params.center = *hit;
          if (auto* g = std::get_if<protocol::CsgToolOp>(&op)) g->params.center = *hit;
        }
        const bool brush = std::holds_alternative<protocol::BrushOp>(op);
        std::optional<Workers::LongTask> longTask;
        if (cost.voxels > kLongOpVoxels) longTask.emplace(self->workers);
        const Progress::Scope scope(*running->progress);
        const ApplyResult a = s.session->apply(op, brush ? ThreadPool::serial() : self->pool);
        running->done();
        r.result = {{"revision", a.revision}, {"roi", protocol::boxJson(a.changed ? a.roi : Box{})}};
        if (p.ray) r.result["hit"] = protocol::vec3Json(*hit);
        if (a.changed) {
          r.record = [op, a] { return json{{"r", a.revision}, {"op", protocol::toJson(op)}}; };
          r.after = [self, &s, c, a] { self->changed(s, *c, "tool", a.roi, a.bricks, a.fullRefresh); };
        }
      });
    }
    case Method::VolumeMorph: {
      const protocol::MorphOp op = protocol::parseMorphParams(req.params);
      const auto running = track(c, req.id);
      return onStrand(c, req.id, arrived, true, [self, c, op, refuseReadOnly, running](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        const OpCost cost = estimateCost(s.session->volume(), op);
        self->checkBudget(cost.voxels, "this morphology");
        running->progress->setTotal(cost.passes);
        std::optional<Workers::LongTask> longTask;
        if (cost.voxels > kLongOpVoxels) longTask.emplace(self->workers);
        const Progress::Scope scope(*running->progress);
        const ApplyResult a = s.session->apply(op, self->pool);
        running->done();
        r.result = {{"revision", a.revision}, {"roi", protocol::boxJson(a.changed ? a.roi : Box{})}};
        if (a.changed) {
          r.record = [op, a] { return json{{"r", a.revision}, {"op", protocol::toJson(protocol::Op(op))}}; };
          r.after = [self, &s, c, a] { self->changed(s, *c, "morph", a.roi, a.bricks, a.fullRefresh); };
        }
      });
    }
    case Method::StrokeBegin: {
      const protocol::StrokeBeginParams p = protocol::parseStrokeBeginParams(req.params);
      return onStrand(c, req.id, arrived, false, [c, p, refuseReadOnly](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        json records = json::array();
        if (c->stroke) {
          try {
            s.session->endStroke(c->stroke);
            records.push_back({{"stroke_end", c->stroke}});
          } catch (const ServiceError&) {
            // The session closed it already (a reload); nothing to end.
          }
          c->stroke = 0;
        }
        const Session::StrokeParams params{p.tool, p.radius, p.strength, Symmetry{p.mirrorX, p.mirrorY, p.mirrorZ},
                                           p.accumulate, {}};
        c->stroke = s.session->beginStroke(params.tool, params.radius, params.strength, params.symmetry,
                                           params.accumulate);
        records.push_back(strokeBeginRecord(c->stroke, params));
        r.record = [records] { return records; };
        r.result = {{"stroke", c->stroke}};
      });
    }
    case Method::StrokeDabs: {
      const protocol::StrokeDabsParams p = protocol::parseStrokeDabsParams(req.params, l.maxDabs);
      const auto running = track(c, req.id);
      return onStrand(c, req.id, arrived, true, [self, c, p, refuseReadOnly, running](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        if (p.stroke != c->stroke)
          throw RpcException(RpcCode::NoSuchStroke, "stroke " + std::to_string(p.stroke) + " is not this connection's open stroke",
                             {{"field", "stroke"}});
        double voxels = 0;
        for (const auto& [id, st] : s.session->openStrokeList())
          if (id == p.stroke) {
            const int images = (st.symmetry.x ? 2 : 1) * (st.symmetry.y ? 2 : 1) * (st.symmetry.z ? 2 : 1);
            voxels = double(p.dabs.size()) * brushVoxels(s.session->volume(), st.radius, images);
          }
        self->checkBudget(voxels, "this message's dabs");
        std::optional<Workers::LongTask> longTask;
        if (voxels > kLongOpVoxels) longTask.emplace(self->workers);
        std::vector<Dab> dabs;
        dabs.reserve(p.dabs.size());
        for (const protocol::DabParam& d : p.dabs) {
          Dab dab;
          if (const auto* center = std::get_if<Vec3>(&d.at)) dab.at = *center;
          else {
            const auto& ray = std::get<protocol::RayParam>(d.at);
            dab.at = Ray{ray.origin, ray.direction};
          }
          dab.pressure = d.pressure;
          dabs.push_back(dab);
        }
        const Progress::Scope scope(*running->progress);
        const ApplyResult a = s.session->strokeDabs(p.stroke, dabs, ThreadPool::serial());
        running->done();
        r.result = {{"revision", a.revision},
                    {"applied", a.changed ? dabs.size() - a.missed : 0},
                    {"roi", protocol::boxJson(a.changed ? a.roi : Box{})}};
        if (a.changed) {
          json applied = json::array();
          for (std::size_t i = 0; i < a.hits.size(); ++i)
            if (a.hits[i]) applied.push_back({a.hits[i]->x, a.hits[i]->y, a.hits[i]->z, p.dabs[i].pressure});
          r.record = [stroke = p.stroke, applied, rev = a.revision] {
            return json{{"r", rev}, {"stroke", stroke}, {"dabs", applied}};
          };
          r.after = [self, &s, c, a] { self->changed(s, *c, "stroke", a.roi, a.bricks, a.fullRefresh); };
        }
      });
    }
    case Method::StrokeEnd: {
      const std::uint64_t stroke = protocol::parseStrokeEndParams(req.params);
      return onStrand(c, req.id, arrived, false, [c, stroke, refuseReadOnly](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        if (stroke != c->stroke)
          throw RpcException(RpcCode::NoSuchStroke, "stroke " + std::to_string(stroke) + " is not this connection's open stroke",
                             {{"field", "stroke"}});
        try {
          s.session->endStroke(stroke);
        } catch (const ServiceError&) {
          // Closed by a reload of the session: ending it again is what the client asked.
        }
        c->stroke = 0;
        r.record = [stroke] { return json{{"stroke_end", stroke}}; };
        r.result = {{"revision", s.session->revision()}, {"can_undo", s.session->canUndo()}, {"can_redo", s.session->canRedo()}};
      });
    }
    case Method::HistoryUndo:
    case Method::HistoryRedo: {
      protocol::parseNoParams(req.params, req.method);
      const bool undo = req.method == Method::HistoryUndo;
      return onStrand(c, req.id, arrived, true, [self, c, undo, refuseReadOnly](LiveSession& s, Reply& r) {
        refuseReadOnly(s);
        const HistoryResult h = undo ? s.session->undo() : s.session->redo();
        if (!h.changed)
          throw RpcException(RpcCode::NothingToUndo, undo ? "nothing to undo" : "nothing to redo");
        r.result = {{"revision", h.revision}, {"can_undo", h.canUndo}, {"can_redo", h.canRedo}};
        r.record = [self, &s, undo, h] {
          const std::string step = self->store->persistent() ? self->store->saveStep(s.id, h.revision, h.restored) : std::string();
          return json{{"r", h.revision}, {undo ? "undo" : "redo", step}};
        };
        r.after = [self, &s, c, h, undo] { self->changed(s, *c, undo ? "undo" : "redo", h.roi, h.bricks, false); };
      });
    }
    case Method::VolumeLoad: {
      const std::uint64_t bytes = protocol::parseVolumeLoadParams(req.params, l.maxBinaryBytes - protocol::kFrameHeaderBytes);
      if (c->session) {
        // The read-only test needs the strand; a view client's upload is then dropped as unanswered.
        auto s = c->session;
        s->strand->post([self, c, s, req, bytes, arrived] {
          if (c->readOnly) {
            self->sendError(*c, req.id, {RpcCode::ReadOnly, "this client joined with the view token: edits are refused", nullptr});
          } else {
            c->load = HubClient::PendingLoad{*req.id, req.frameId, bytes, arrived};
          }
          self->finish(c);
        });
      }
      return;
    }
    default:
      throw RpcException(RpcCode::Internal, "unhandled method");
  }
}

void Hub::Impl::read(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived) {
  const HubLimits& l = limits();
  auto self = shared_from_this();
  switch (req.method) {
    case Method::SessionLeave: {
      protocol::parseNoParams(req.params, req.method);
      return onStrand(c, req.id, arrived, false, [self, c](LiveSession& s, Reply& r) {
        self->leave(s, *c);
        r.result = {{"session", s.id}};
        c->session.reset();
      });
    }
    case Method::SessionStats: {
      protocol::parseNoParams(req.params, req.method);
      // The measures read every brick: off the strand, on the snapshot, so edits go on meanwhile.
      return offStrand(
          c, req.id,
          [](const Volume& vol, std::uint64_t, Reply& r) {
            const Measures m = measure(vol);
            r.result["digest"] = m.digest;
            r.result["inside_volume"] = m.insideVolume;
            r.result["surface_area"] = m.surfaceArea;
            r.result["components"] = m.components;
            r.result["bounds"] = {{"empty", m.bounds.empty}, {"lo", protocol::vec3Json(m.bounds.lo)}, {"hi", protocol::vec3Json(m.bounds.hi)}};
            r.result["gradient_error"] = {{"max", m.gradientError.max}, {"mean", m.gradientError.mean}, {"voxels", m.gradientError.voxels}};
          },
          [](LiveSession& s, Reply& r) {
            const SessionStats st = s.session->counters();
            r.result = {{"session", s.id},
                        {"size", sizeJson(s.session->volume().dims())},
                        {"revision", st.revision},
                        {"clients", clientsJson(s)},
                        {"memory_bytes", st.memoryBytes},
                        {"history_bytes", st.historyBytes},
                        {"can_undo", st.canUndo},
                        {"can_redo", st.canRedo}};
          });
    }
    case Method::ViewSet: {
      const protocol::ViewSetParams p = protocol::parseViewSetParams(req.params, l.maxFrameSide);
      return onStrand(c, req.id, arrived, false, [self, c, p](LiveSession& s, Reply& r) {
        c->mode = p.mode;
        if (p.camera) c->camera = *p.camera;
        c->shading = p.shading;
        c->thicknessMinVu = p.minVu;
        r.result = {{"mode", protocol::nameOf(protocol::kViewModeNames, p.mode)}, {"revision", s.session->revision()}};
        r.after = [self, &s, c] {
          if (c->mode == ViewMode::Splats) self->sendFullSplats(s, *c, 0);
          if (c->mode == ViewMode::Frames) self->requestFrame(s, c);
        };
      });
    }
    case Method::RenderFrame: {
      const protocol::RenderFrameParams p = protocol::parseRenderFrameParams(req.params, l.maxFrameSide);
      const std::uint32_t frameId = req.frameId;
      return offStrand(c, req.id, [self, p, frameId](const Volume& vol, std::uint64_t revision, Reply& r) {
        const Frame f = render(vol, p.camera, p.shading, self->pool, FrameQuality::Still, p.minVu);
        const bool png = p.format == protocol::ImageKind::Png;
        const Bytes file = png ? encodePng(f.rgb, f.width, f.height) : encodeJpeg(f.rgb, f.width, f.height, p.quality);
        r.frame = makeFrame(png ? protocol::FrameKind::FramePng : protocol::FrameKind::FrameJpeg, frameId, revision, file);
        r.result = {{"revision", revision}, {"width", f.width}, {"height", f.height}, {"format", png ? "png" : "jpeg"},
                    {"bytes", file.size()}};
      });
    }
    case Method::SplatsGet: {
      protocol::parseNoParams(req.params, req.method);
      const std::uint32_t frameId = req.frameId;
      return offStrand(c, req.id, [self, frameId](const Volume& vol, std::uint64_t revision, Reply& r) {
        // At most one point per voxel of a stored brick, 8 bytes each (uniform bricks yield
        // points only where a -band brick meets a +band one; max_volume_bytes bounds those).
        const std::size_t estimate = vol.presentBricks() * (8 + 8 * std::size_t(kBrickVoxels));
        if (estimate > self->limits().maxOutputBytes)
          throw RpcException(RpcCode::LimitExceeded,
                             "the splat buffer could reach " + std::to_string(estimate) + " bytes, over max_output_bytes " +
                                 std::to_string(self->limits().maxOutputBytes),
                             {{"limit", "max_output_bytes"}, {"value", estimate}, {"max", self->limits().maxOutputBytes}});
        std::size_t bricks = 0, points = 0;
        r.frame = self->fullSplatsFrame(vol, frameId, revision, &bricks, &points);
        r.result = {{"revision", revision}, {"bricks", bricks}, {"points", points},
                    {"bytes", r.frame->size() - protocol::kFrameHeaderBytes}};
      });
    }
    case Method::MeshExport: {
      const protocol::MeshExportParams p = protocol::parseMeshExportParams(req.params);
      const std::string format = p.format;
      const std::uint32_t frameId = req.frameId;
      return offStrand(c, req.id, [self, p, format, frameId](const Volume& vol, std::uint64_t revision, Reply& r) {
        const std::size_t estimate = crossedEdges(vol) * meshBytesPerEdge(format);
        if (estimate > self->limits().maxOutputBytes)
          throw RpcException(RpcCode::LimitExceeded,
                             "the mesh file would be about " + std::to_string(estimate) + " bytes, over max_output_bytes " +
                                 std::to_string(self->limits().maxOutputBytes),
                             {{"limit", "max_output_bytes"}, {"value", estimate}, {"max", self->limits().maxOutputBytes}});
        Mesh mesh = extractMesh(vol, self->pool);
        std::optional<DecimateResult> decimated;
        if (p.maxTriangles || p.maxError) {
          decimated = decimateMesh(mesh, vol, {p.maxTriangles, p.maxError}, self->pool);
          mesh = std::move(decimated->mesh);
        }
        const MeshFormat f = *meshFormatFromName(format);
        const Bytes file = exportMesh(mesh, f);
        if (file.size() > protocol::kMaxFramePayload)
          throw RpcException(RpcCode::LimitExceeded, "the mesh file is larger than one frame can carry (4 GiB)",
                             {{"limit", "frame_payload"}, {"max", protocol::kMaxFramePayload}});
        const auto kind = format == "stl"   ? protocol::FrameKind::MeshStl
                          : format == "obj" ? protocol::FrameKind::MeshObj
                          : format == "glb" ? protocol::FrameKind::MeshGlb
                                            : protocol::FrameKind::MeshPly;
        r.frame = makeFrame(kind, frameId, revision, file);
        r.result = {{"revision", revision}, {"format", format}, {"vertices", mesh.vertexCount()},
                    {"triangles", mesh.triangleCount()}, {"bytes", file.size()}};
        if (decimated) {
          r.result["source_triangles"] = decimated->sourceTriangles;
          r.result["max_error"] = decimated->maxError;
        }
      });
    }
    case Method::AnalysisThickness: {
      const protocol::ThicknessParams p = protocol::parseThicknessParams(req.params);
      return offStrand(c, req.id, [self, p](const Volume& vol, std::uint64_t revision, Reply& r) {
        const ThicknessReport t = analyzeThickness(vol, p.minVu, p.maxPlaces, 4.0, self->pool);
        json places = json::array();
        for (const ThinPlace& q : t.places)
          places.push_back({{"point", protocol::vec3Json(q.point)}, {"normal", protocol::vec3Json(q.normal)},
                            {"thickness", q.thickness}});
        r.result = {{"revision", revision}, {"min_vu", p.minVu}, {"points", t.points}, {"below", t.below},
                    {"thinnest", t.points ? json(t.thinnest) : json(nullptr)}, {"places", places}};
      });
    }
    case Method::VolumeSave: {
      protocol::parseNoParams(req.params, req.method);
      const std::uint32_t frameId = req.frameId;
      return offStrand(c, req.id, [frameId](const Volume& vol, std::uint64_t revision, Reply& r) {
        const Bytes file = saveVolume(vol);
        r.frame = makeFrame(protocol::FrameKind::VolumeFile, frameId, revision, file);
        r.result = {{"revision", revision}, {"digest", digestHex(vol)}, {"bytes", file.size()}};
      });
    }
    default:
      throw RpcException(RpcCode::Internal, "unhandled method");
  }
}

Hub::Hub(HubOptions options) : impl_(std::make_shared<Impl>(std::move(options))) {
  impl_->store->onLost([weak = std::weak_ptr<Impl>(impl_)](const std::string& id) {
    if (const auto impl = weak.lock()) impl->leaseLost(id);
  });
  impl_->sweepOldSessions(std::chrono::milliseconds(0));
}

Hub::~Hub() { shutdown(); }

const HubLimits& Hub::limits() const { return impl_->limits(); }

std::shared_ptr<HubClient> Hub::connect(std::shared_ptr<ClientLink> link, std::string peer) {
  auto c = std::make_shared<HubClient>(std::move(link), std::move(peer));
  impl_->scheduleLobbyCheck(c, std::chrono::duration_cast<std::chrono::milliseconds>(impl_->limits().lobby));
  return c;
}

bool Hub::mayUpload(const std::shared_ptr<HubClient>& client) const { return client->editor; }

void Hub::text(const std::shared_ptr<HubClient>& client, std::string message) {
  // op.cancel overtakes the connection's queue (the request it stops is ahead in it); only a
  // message as short as a real one is looked at, so big texts cannot skip the rate limit.
  if (message.size() <= kMaxCancelBytes && message.find("op.cancel") != std::string::npos && impl_->cancel(client, message))
    return;
  impl_->enqueue(client, {std::move(message), Clock::now()});
}

void Hub::binary(const std::shared_ptr<HubClient>& client, std::vector<std::uint8_t> message) {
  impl_->enqueue(client, {std::move(message), Clock::now()});
}

void Hub::disconnect(const std::shared_ptr<HubClient>& client) {
  {
    const std::lock_guard lock(client->mutex);
    if (client->closed) return;
    client->closed = true;
    client->queue.clear();
    if (client->busy) return;  // the running pump cleans up when it finishes
    client->busy = true;
  }
  impl_->workers.post([impl = impl_, client] { impl->cleanup(client); });
}

void Hub::shutdown() {
  Impl& s = *impl_;
  std::vector<std::shared_ptr<LiveSession>> all;
  {
    const std::lock_guard lock(s.mutex);
    if (s.stopping) return;
    s.stopping = true;
    for (const auto& [id, live] : s.sessions) all.push_back(live);
  }
  // Long operations stop at their next chunk or dab and change nothing; the others finish.
  {
    const std::lock_guard lock(s.mutex);
    for (Progress* p : s.runningOps) p->cancel();
  }
  const auto deadline = Clock::now() + kShutdownWait;
  for (const auto& live : all)
    while (live->strand->pending() > 0 && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  if (s.store->persistent()) {
    // Every snapshot is posted at once; one that is not done by the deadline still runs when
    // the workers stop (they finish queued tasks), and the journal holds its changes anyway.
    std::vector<std::future<void>> snapshots;
    for (const auto& live : all) {
      auto done = std::make_shared<std::promise<void>>();
      snapshots.push_back(done->get_future());
      live->strand->post([&s, live, done] {
        if (!live->unloaded && live->session && live->journal) {
          try {
            live->journal = s.store->snapshot(live->id, live->session->volume());
          } catch (const std::exception& e) {
            s.log("session " + live->id + ": snapshot at shutdown failed (the journal has every change): " + e.what());
          }
          live->journal.reset();
          s.releaseLease(*live);
          // An edit that reaches the strand after this (dispatched just before `stopping`)
          // finds the session closed instead of being acknowledged without a journal.
          live->unloaded = true;
        }
        done->set_value();
      });
    }
    const auto snapshotDeadline = Clock::now() + kShutdownWait;
    for (const auto& f : snapshots) f.wait_until(snapshotDeadline);
  }
  s.workers.stop();
  const std::lock_guard lock(s.mutex);
  s.sessions.clear();
}

std::size_t Hub::sessionCount() const {
  const std::lock_guard lock(impl_->mutex);
  return impl_->sessions.size();
}

}  // namespace marzipan::service
