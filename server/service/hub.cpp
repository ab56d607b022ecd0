// The hub (see hub.hpp): the facade over HubCore (service/hub/core.hpp, which maps the pieces),
// each connection's pump, and the dispatch of requests through the method table
// (service/hub/methods.hpp).
//
// How a message travels: text()/binary() append it to the connection's queue
// (service/hub/connection.hpp); one pump task at a time takes the next message, parses it
// (protocol/cpp/rpc.hpp), finds its method's row and hands the request to its handler, which
// posts the work to the session's strand. Only when that work has sent its answer does the pump
// take the next message, so a connection's answers come in request order. A small text is
// pumped by whoever has the connection in hand (the network thread it arrived on, or the worker
// that finished the message before it) and a method's work handed to the strand from there
// (unless it is a slow one); the rest goes through the workers (HubCore::PumpOn).
#include "service/hub.hpp"

#include <future>
#include <thread>

#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"
#include "service/hub/outbox.hpp"
#include "service/hub/secrets.hpp"
#include "service/session_store.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;

namespace {

// Shutdown waits this long for running edits (long ones are cancelled), then as long again
// for the snapshots: with the network's grace period it exits within 10 s of SIGTERM.
constexpr std::chrono::milliseconds kShutdownWait{2'000};

// {"jsonrpc":"2.0","id":...,"method":"op.cancel","params":{}} with room for a long string id.
constexpr std::size_t kMaxCancelBytes = 256;

// The storage the options name: theirs, files in the data directory, or none.
std::shared_ptr<SessionStorage> openStorage(const HubOptions& o, const std::string& owner) {
  if (o.storage) return o.storage;
  if (o.dataDir.empty()) return makeMemoryStorage();
  return std::make_shared<SessionStore>(o.dataDir, o.fsyncInterval, o.events.log, owner);
}

}  // namespace

HubCore::HubCore(HubOptions o)
    : options(std::move(o)),
      owner(options.serverId.empty() ? randomText(16) : options.serverId),
      store(openStorage(options, owner)),
      workers(options.workers, options.events.log),
      pool(int(workers.threads())) {}

// --- the connection's queue and pump -------------------------------------------------------------

namespace {

// Pumps running on this thread (HubCore::pump, handle): finish then hands the next message to
// the workers instead of pumping it inside the one before.
thread_local int tPumping = 0;

struct Pumping {
  Pumping() { ++tPumping; }
  ~Pumping() { --tPumping; }
  Pumping(const Pumping&) = delete;
  Pumping& operator=(const Pumping&) = delete;
};

}  // namespace

void HubCore::enqueue(const std::shared_ptr<HubClient>& c, Incoming in) {
  const bool inlineSized = isInlineSized(in);
  const ConnectionQueue::Admission a = c->queue.push(in, limits(), Clock::now());
  // On an idle connection a small text is parsed here, on the caller's (network) thread, and a
  // method that is not slow (a presence, a stroke's messages) handed over from here: see PumpOn.
  if (a.start) {
    if (inlineSized) pump(c, PumpOn::Network);
    else pumpOnWorkers(c);
  }
  if (a.queued || a.refusal.empty()) return;
  // Answered at once without queueing, outside the queue's lock: the link may send inline and,
  // past its queue bound, disconnect this client. An upload cannot be answered alone: its
  // volume.load then fails with -32013. The id is peeked, not parsed: a flood of 1 MiB texts
  // past the rate limit would otherwise cost this network thread a full parse each.
  if (const auto* text = std::get_if<std::string>(&in.message)) {
    const std::optional<protocol::PeekedId> peeked = protocol::peekRequestId(*text);
    sendError(*c, peeked ? peeked->id : json(nullptr), peeked && peeked->notification,
              {RpcCode::Busy, a.refusal, {{"retry_after_ms", 100}}});
  }
}

void HubCore::finish(const std::shared_ptr<HubClient>& c) {
  // What the message's work sent goes ahead of anything its connection's next message sends.
  Outbox::flush();
  switch (c->queue.finished()) {
    case ConnectionQueue::Next::Idle: return;
    case ConnectionQueue::Next::Closed: return cleanup(c);
    case ConnectionQueue::Next::Message:
      if (tPumping > 0) pumpOnWorkers(c);
      else pump(c, PumpOn::AfterWork);
  }
}

void HubCore::cleanup(const std::shared_ptr<HubClient>& c) {
  c->load.reset();
  const std::shared_ptr<LiveSession> s = c->session;
  if (!s) return;
  s->strand->post([self = shared_from_this(), s, c] {
    if (!s->unloaded && s->session) self->registry.leave(*s, *c);
    c->session.reset();
  });
}

bool HubCore::isInlineSized(const Incoming& in) {
  const auto* text = std::get_if<std::string>(&in.message);
  return text && text->size() <= kMaxInlineBytes;
}

void HubCore::pumpOnWorkers(const std::shared_ptr<HubClient>& c) {
  workers.post([self = shared_from_this(), c] { self->pump(c, PumpOn::Worker); });
}

void HubCore::pump(const std::shared_ptr<HubClient>& c, PumpOn on) {
  const Pumping pumping;
  Incoming in;
  switch (c->queue.take(in)) {
    case ConnectionQueue::Next::Idle: return;
    case ConnectionQueue::Next::Closed: return cleanup(c);
    case ConnectionQueue::Next::Message: break;
  }
  if (on != PumpOn::Worker && !isInlineSized(in)) {
    workers.post([self = shared_from_this(), c, in = std::move(in)]() mutable {
      self->handle(c, std::move(in), PumpOn::Worker);
    });
    return;
  }
  handle(c, std::move(in), on);
}

void HubCore::handle(const std::shared_ptr<HubClient>& c, Incoming in, PumpOn on) {
  const Pumping pumping;
  try {
    if (auto* bytes = std::get_if<Bytes>(&in.message)) return volumeUpload(*this, c, std::move(*bytes));
    if (c->load) {
      const HubClient::PendingLoad load = *c->load;
      c->load.reset();
      sendError(*c, load.id, false,
                {RpcCode::UploadMissing, "volume.load was not followed by its upload (a kind-9 binary frame with request id " +
                                             std::to_string(load.frameId) + ")", nullptr});
    }
    handleText(c, std::get<std::string>(in.message), in.arrived, on);
  } catch (...) {
    sendError(*c, json(nullptr), false, failureOf(std::current_exception(), options.events.log));
    finish(c);
  }
}

// --- dispatch --------------------------------------------------------------------------------------

void HubCore::handleText(const std::shared_ptr<HubClient>& c, const std::string& text, Clock::time_point arrived,
                         PumpOn on) {
  protocol::ParsedRequest parsed = protocol::parseRequest(text);
  if (!parsed.request) {
    const protocol::RpcError& e = *parsed.error;
    sendError(*c, e.id, e.notification, {e.code, e.message, e.data});
    return finish(c);
  }
  const MethodEntry* method = findMethod(parsed.request->method);
  if (on != PumpOn::Worker && (!method || method->slow)) {
    workers.post([self = shared_from_this(), c, req = std::move(*parsed.request), arrived] {
      const Pumping pumping;
      try {
        self->dispatch(c, req, arrived);
      } catch (...) {
        self->sendError(*c, req.id, failureOf(std::current_exception(), self->options.events.log));
        self->finish(c);
      }
    });
    return;
  }
  dispatch(c, *parsed.request, arrived);
}

void HubCore::dispatch(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived) {
  if (options.events.request) options.events.request(protocol::nameOf(protocol::kMethodNames, req.method));
  // A binary-answered method sent as a notification has nowhere to put its answer.
  if (!req.id && protocol::needsFrameId(req.method)) return finish(c);
  if (stopping()) {
    sendError(*c, req.id, {RpcCode::Busy, "the server is shutting down", nullptr});
    return finish(c);
  }
  try {
    const MethodEntry* method = findMethod(req.method);
    if (method && method->access != Access::Anyone && !c->session)
      throw RpcException(RpcCode::NotInSession, "not in a session: session.create or session.join first");
    if (!method) throw RpcException(RpcCode::Internal, "unhandled method");
    method->handle(*this, Call{c, req, arrived, method->access});
  } catch (...) {
    sendError(*c, req.id, failureOf(std::current_exception(), options.events.log));
    finish(c);
  }
}

bool HubCore::cancel(const std::shared_ptr<HubClient>& c, const std::string& text) {
  const protocol::ParsedRequest parsed = protocol::parseRequest(text);
  if (!parsed.request || parsed.request->method != protocol::Method::OpCancel) return false;
  const protocol::Request& req = *parsed.request;
  if (options.events.request) options.events.request("op.cancel");
  if (c->queue.closed()) return true;
  const std::shared_ptr<Progress> running = c->running();
  try {
    protocol::parseNoParams(req.params, protocol::Method::OpCancel);
  } catch (...) {
    sendError(*c, req.id, failureOf(std::current_exception(), options.events.log));
    return true;
  }
  if (running) running->cancel();
  sendResult(*c, req.id, {{"cancelled", running != nullptr}});
  return true;
}

// --- the facade ------------------------------------------------------------------------------------

Hub::Hub(HubOptions options) : impl_(std::make_shared<HubCore>(std::move(options))) {
  impl_->store->onLost([weak = std::weak_ptr<HubCore>(impl_)](const std::string& id) {
    if (const auto core = weak.lock()) core->durability.leaseLost(id);
  });
  impl_->durability.sweepOldSessions(std::chrono::milliseconds(0));
}

Hub::~Hub() { shutdown(); }

const HubLimits& Hub::limits() const { return impl_->limits(); }

std::shared_ptr<HubClient> Hub::connect(std::shared_ptr<ClientLink> link, std::string peer) {
  auto c = std::make_shared<HubClient>(std::make_shared<HeldLink>(std::move(link)), std::move(peer));
  impl_->registry.scheduleLobbyCheck(c, std::chrono::duration_cast<std::chrono::milliseconds>(impl_->limits().lobby));
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
  if (client->queue.close()) impl_->workers.post([core = impl_, client] { core->cleanup(client); });
}

void Hub::shutdown() {
  HubCore& core = *impl_;
  if (!core.stop()) return;
  const std::vector<std::shared_ptr<LiveSession>> all = core.registry.all();
  const auto deadline = Clock::now() + kShutdownWait;
  for (const auto& live : all)
    while (live->strand->pending() > 0 && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  if (core.store->persistent()) {
    // Every snapshot is posted at once; one that is not done by the deadline still runs when
    // the workers stop (they finish queued tasks), and the journal holds its changes anyway.
    std::vector<std::future<void>> snapshots;
    for (const auto& live : all) {
      auto done = std::make_shared<std::promise<void>>();
      snapshots.push_back(done->get_future());
      live->strand->post([&core, live, done] {
        if (!live->unloaded && live->session && live->journal) {
          core.durability.saveAndRelease(*live, "shutdown");
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
  core.workers.stop();
  core.registry.clear();
}

std::size_t Hub::sessionCount() const { return impl_->registry.count(); }

}  // namespace marzipan::service
