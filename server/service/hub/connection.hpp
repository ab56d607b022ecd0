// One connection as the hub sees it (HubClient), and the queue of its messages not yet handled
// with the bounds that keep one connection from flooding the workers (ConnectionQueue).
//
// Conventions:
// - Threads: HubClient's fields are grouped by the one context that may touch them (the queue's
//   lock, the connection's pump, its session's strand); the atomics are read anywhere.
// - A connection's messages are handled one at a time: whoever takes one from the queue owns the
//   connection ("busy") until it calls finished().
// - Sizes in bytes; rates in requests per second.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/progress.hpp"
#include "protocol/cpp/rpc.hpp"
#include "protocol/cpp/values.hpp"
#include "service/hub.hpp"
#include "service/session.hpp"

namespace marzipan::service {

using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;
using SharedBytes = std::shared_ptr<const Bytes>;

struct LiveSession;

// One message as it arrived: a text (JSON-RPC) or a binary frame (an upload).
struct Incoming {
  std::variant<std::string, Bytes> message;
  Clock::time_point arrived;
  std::size_t size() const {
    return std::visit([](const auto& m) { return m.size(); }, message);
  }
};

// The messages of one connection not yet handled. A message is refused (not queued) when
// max_pending_messages wait already, when the connection sent more than max_requests_per_second
// (a token bucket holding two seconds' worth), or when the bytes waiting would pass
// max_binary_bytes + max_text_bytes. Thread-safe.
class ConnectionQueue {
 public:
  struct Admission {
    bool queued = false;
    bool start = false;   // queued, and no one owns the connection: the caller starts a pump
    std::string refusal;  // why it was refused (-32005), when neither queued nor closed
  };
  // Queues `in` (moving from it) unless the connection is closed or over a bound.
  Admission push(Incoming& in, const HubLimits& limits, Clock::time_point now);

  enum class Next { Message, Idle, Closed };
  // For the owner: the next message (Message), none (Idle: the owner lets go) or Closed (the
  // owner keeps the connection to clean up).
  Next take(Incoming& out);
  // For the owner, after one message: Idle (let go), Message (one waits: take it next) or Closed
  // (clean up).
  Next finished();
  // For the owner, while it handles a message: the next message waiting, taken out, when it is a
  // text (false: none, a binary frame, or the connection is closed). It counts as handled unless
  // given back with putBack. How the handler of a stroke.dabs takes the same stroke's messages
  // queued right behind it (service/hub/methods_edit.cpp).
  bool takeText(Incoming& out);
  // For the owner: puts a message taken with takeText back in front of the queue (the last
  // taken first), to be handled in its turn. Dropped when the connection closed meanwhile.
  void putBack(Incoming in);
  // The connection is gone: drops what waits. True when no one owned it: the caller does now,
  // and cleans up.
  bool close();
  bool closed() const;

 private:
  mutable std::mutex mutex_;
  std::deque<Incoming> queue_;
  bool busy_ = false;
  bool closed_ = false;
  std::size_t bytes_ = 0;
  double tokens_ = 1e9;  // requests it may still send now (capped at the first refill)
  Clock::time_point refilled_ = Clock::now();
};

class HubClient {
 public:
  HubClient(std::shared_ptr<ClientLink> l, std::string p) : link(std::move(l)), peer(std::move(p)) {}

  const std::shared_ptr<ClientLink> link;
  const std::string peer;
  ConnectionQueue queue;

  // Its long request in progress, for op.cancel (which overtakes the queue).
  std::shared_ptr<Progress> running() const {
    const std::lock_guard lock(runningMutex_);
    return running_;
  }
  void setRunning(std::shared_ptr<Progress> p) {
    const std::lock_guard lock(runningMutex_);
    running_ = std::move(p);
  }
  // Clears the running request if it is still p.
  void clearRunning(const std::shared_ptr<Progress>& p) {
    const std::lock_guard lock(runningMutex_);
    if (running_ == p) running_.reset();
  }

  // The pump only (one message at a time, so no lock is needed).
  std::shared_ptr<LiveSession> session;
  struct PendingLoad {  // a volume.load waiting for its upload
    nlohmann::json id;
    std::uint32_t frameId;
    std::uint64_t bytes;
    Clock::time_point arrived;
    protocol::VolumeFormat format;
  };
  std::optional<PendingLoad> load;
  std::deque<Clock::time_point> creates;  // this connection's session.create in the last minute

  // Written on the session's strand, read anywhere: an editor of a session (may upload), a
  // member of one, and since when it is in none (for the lobby deadline).
  std::atomic<bool> editor{false}, member{false};
  std::atomic<Clock::rep> outsideSince{Clock::now().time_since_epoch().count()};

  // The session's strand only; clientId, readOnly, name and color are also read by the pump
  // while it is a member (they change only in admit, before the pump sees its session).
  int clientId = 0;
  bool readOnly = false;
  std::string name, color;  // display name and "#rrggbb" (since 1.2)
  protocol::ViewMode mode = protocol::ViewMode::None;
  // The splat buffer version it reads (session.create/join `splats`, since 1.7; protocol/cpp/splats.hpp): 1
  // drops the colour; a fork keeps it.
  int splats = protocol::kSplatsVersionDefault;
  Camera camera;
  Shading shading = Shading::Lit;
  double thicknessMinVu = 1;
  StrokeId stroke = 0;
  std::uint64_t frameSeq = 0;  // bumped by every change or camera change
  bool rendering = false, renderAgain = false;

 private:
  mutable std::mutex runningMutex_;
  std::shared_ptr<Progress> running_;
};

}  // namespace marzipan::service
