// What every piece of the hub shares (HubCore): the options, the storage, the workers, the
// registry, durability and broadcasting, and how a request's work runs and is answered. The
// facade (service/hub.hpp) owns one HubCore; each piece holds a reference to it, and every task
// posted to the workers holds a shared_ptr to it, so it outlives the work in flight.
//
// Where things are (service/hub/):
//   secrets       ids and tokens, constant-time compare
//   rpc_errors    exception -> JSON-RPC error (code, message, data)
//   connection    HubClient and its message queue with the rate limiter
//   live_session  a loaded session: Session, journal, strand, clients
//   registry      create/find/load, admit/leave, unload/idle, the lobby deadline
//   durability    persist and roll back, snapshots, fsync timer, leases, old-session sweep
//   broadcast     session.changed/clients, splat buffers, the frame-push state machine
//   presence_relay names, colours and presence notifications, coalesced per sender
//   request       Call, Access, Reply: a request as its handler sees it
//   methods       the table of methods (name -> handler, access rule) and the handlers
//   work.cpp      onStrand/offStrand, long operations (progress, cancel, budget), sending
// service/hub.cpp keeps the facade, the connection's pump and the dispatch through the table.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "engine/progress.hpp"
#include "engine/thread_pool.hpp"
#include "service/hub.hpp"
#include "service/hub/broadcast.hpp"
#include "service/hub/connection.hpp"
#include "service/hub/durability.hpp"
#include "service/hub/live_session.hpp"
#include "service/hub/presence_relay.hpp"
#include "service/hub/registry.hpp"
#include "service/hub/request.hpp"
#include "service/hub/rpc_errors.hpp"
#include "service/session_storage.hpp"
#include "service/workers.hpp"

namespace marzipan::service {

// op.progress notifications of one request come at most this often.
inline constexpr std::chrono::milliseconds kProgressInterval{250};
// A request estimated above this many voxels (about 2 s here) runs as a Workers::LongTask.
inline constexpr double kLongOpVoxels = 2e7;

struct HubCore : std::enable_shared_from_this<HubCore> {
  explicit HubCore(HubOptions o);

  HubOptions options;
  const std::string owner;  // this server's name in leases
  const std::shared_ptr<SessionStorage> store;
  Workers workers;
  ThreadPool pool;  // for whole-volume kernels and renders; parallelFor serializes its callers
  SessionRegistry registry{*this};
  Durability durability{*this};
  Broadcaster broadcast{*this};
  PresenceRelay presence{*this};

  const HubLimits& limits() const { return options.limits; }
  void log(const std::string& line) const {
    if (options.events.log) options.events.log(line);
  }
  static void emit(const std::function<void(std::int64_t)>& f, std::int64_t v) {
    if (f) f(v);
  }

  // --- shutting down (guarded by mutex) ----------------------------------------------------------
  bool stopping() const;
  // Sets stopping and cancels every long operation; false when it was set already.
  bool stop();

  // --- answering ---------------------------------------------------------------------------------
  void sendResult(HubClient& c, const std::optional<nlohmann::json>& id, const nlohmann::json& result);
  // The result's text when it was written directly (resultJson not empty), else `result`'s.
  void sendResult(HubClient& c, const std::optional<nlohmann::json>& id, const nlohmann::json& result,
                  const std::string& resultJson);
  // A result written as text (JSON of an object).
  void sendResultText(HubClient& c, const std::optional<nlohmann::json>& id, std::string_view resultJson);
  void sendError(HubClient& c, const nlohmann::json& id, bool notification, const Failure& f);
  void sendError(HubClient& c, const std::optional<nlohmann::json>& id, const Failure& f);

  // --- the connection's pump (service/hub.cpp) -----------------------------------------------------
  void enqueue(const std::shared_ptr<HubClient>& c, Incoming in);
  // Ends the handling of one message: the connection's next one may start. Every handler's
  // work ends with it (onStrand and offStrand call it).
  void finish(const std::shared_ptr<HubClient>& c);
  // After a disconnect, by whoever owns the connection then.
  void cleanup(const std::shared_ptr<HubClient>& c);
  // op.cancel, handled on the caller's thread ahead of the queue. False when text is not one.
  bool cancel(const std::shared_ptr<HubClient>& c, const std::string& text);

  // --- running a request's work (work.cpp) ---------------------------------------------------------
  // Runs fn on the strand of c's session: checks the session is open and (for Access::Editor)
  // that c may edit, journals r.record, sends r.frame and the result, runs r.after, then lets
  // the connection's next message start. edit: fn is an edit (a tool, dabs, a morph,
  // undo, redo, a load): its latency goes to HubEvents::editLatency, and when it changed
  // nothing the lease is confirmed before it is answered (Durability::confirmHeld).
  void onStrand(const Call& call, bool edit, std::function<void(LiveSession&, Reply&)> fn);
  // The same on the strand of s, which c need not be a client of (yet): session.create/join,
  // and the upload of a volume.load.
  void onStrand(const std::shared_ptr<HubClient>& c, std::shared_ptr<LiveSession> s, const std::optional<nlohmann::json>& id,
                Clock::time_point arrived, bool edit, Access access, std::function<void(LiveSession&, Reply&)> fn);
  // Takes a snapshot on the strand, then runs fn on the workers off the strand (renders,
  // exports, measures), answers and lets the connection go on. atStrand, when given, starts
  // the reply on the strand with what needs the live session. at: the snapshot is the volume
  // at that revision instead (Session::versionAt): the session's kept version, or rebuilt on
  // the workers (cancellable, within max_op_voxels, then kept); -32602 field "revision" when
  // the history has no such step.
  void offStrand(const Call& call, std::function<void(const Volume&, std::uint64_t revision, Reply&)> fn,
                 std::function<void(LiveSession&, Reply&)> atStrand = {}, std::optional<std::uint64_t> at = std::nullopt);
  // -32007 when c joined with the view token and the call needs edit rights (on the strand).
  static void checkAccess(const HubClient& c, Access access);

  // One long request's Progress (engine/progress.hpp): op.progress notifications to its
  // client, cancelled by that client's op.cancel or by shutdown. Registered from track() until
  // done() or its destruction (it is captured by the request's strand task).
  struct RunningOp {
    std::shared_ptr<HubCore> hub;
    std::shared_ptr<HubClient> client;
    std::shared_ptr<Progress> progress;
    bool registered = true;
    void done();
    ~RunningOp() { done(); }
  };
  std::shared_ptr<RunningOp> track(const std::shared_ptr<HubClient>& c, const std::optional<nlohmann::json>& id);
  // Refuses a request whose estimated work is over max_op_voxels (-32004), before anything runs.
  void checkBudget(double voxels, const char* what) const;
  // Runs rb with running's progress and cancel (off the strand; a long task when it is large).
  Volume build(const Rebuild& rb, RunningOp& running);
  // On s's strand: hands `then` (on the strand) the volume of s at `revision`: at once when it
  // is the current or the kept version, else rebuilt on the workers within max_op_voxels with
  // running's cancel, and kept. One rebuild per session at a time: a request needing one while
  // another runs waits for it and tries again (the same revision is then kept). fail gets what
  // went wrong (-32602 "revision", -32004, -32016), on the strand or a worker.
  void withVersion(const std::shared_ptr<LiveSession>& s, std::uint64_t revision, const std::shared_ptr<RunningOp>& running,
                   std::function<void(std::shared_ptr<const Volume>)> then, std::function<void(std::exception_ptr)> fail);
  // On s's strand, when its rebuild ended: the requests waiting for it try again, in order.
  void rebuildEnded(LiveSession& s);
  // After an edit, on the strand: ends the open strokes idle for stroke_idle, then the oldest
  // while the old bricks they hold are over max_volume_bytes (Session::endStaleStrokes), as
  // stroke.end would: their stroke_end records follow the edit's in r.record.
  void endStaleStrokes(LiveSession& s, Reply& r);

 private:
  mutable std::mutex mutex_;  // guards stopping_ and runningOps_
  bool stopping_ = false;
  std::set<Progress*> runningOps_;

  // Where a connection's next message is taken and parsed. A small text is handled on the
  // thread that has the connection in hand: the network thread it arrived on (an idle
  // connection), or the worker that just finished the message before it (AfterWork). Parsing it
  // and posting its work to the strand takes microseconds, where a hop through the
  // workers' queue waited behind every busy session's turn (under load, a round of all the
  // sessions' applications, for every message). Slow methods (MethodEntry), bigger texts and uploads go to
  // the workers, as does the next message when this thread is pumping already (a message
  // answered without work calls finish from inside the pump: no recursion however many wait).
  enum class PumpOn { Worker, Network, AfterWork };
  // Small: the parse stays in microseconds for every connection sharing the network thread. A
  // web client's stroke.dabs of one display frame (a few dabs of about 150 bytes) or a presence
  // is far below; a backlog of dabs merged into one message may not be, and takes the workers.
  static constexpr std::size_t kMaxInlineBytes = 4 * 1024;
  static bool isInlineSized(const Incoming& in);
  // Handles the connection's next message.
  void pump(const std::shared_ptr<HubClient>& c, PumpOn on);
  // The same, on a worker.
  void pumpOnWorkers(const std::shared_ptr<HubClient>& c);
  void handle(const std::shared_ptr<HubClient>& c, Incoming in, PumpOn on);
  void handleText(const std::shared_ptr<HubClient>& c, const std::string& text, Clock::time_point arrived, PumpOn on);
  // A parsed request to its method's handler, through the table.
  void dispatch(const std::shared_ptr<HubClient>& c, const protocol::Request& req, Clock::time_point arrived);
  void handleBinary(const std::shared_ptr<HubClient>& c, Bytes bytes);
};

}  // namespace marzipan::service
