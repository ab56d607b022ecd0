// Presence of a session's clients (brush, pointer, camera), coalesced for forwarding: no
// sockets, no JSON, no timers. The owner (the hub) feeds every client's updates in and, for
// each receiver, takes what may be sent now; it arms its own timer for nextDue().
//
// Conventions:
// - Rate: a receiver gets each other sender's updates at most once per interval (default
//   50 ms: 20 per second per sender), measured between deliveries of that pair on the
//   injected clock: two deliveries of one sender to one receiver are at least `interval` apart.
// - Latest wins: a sender has one pending update, its newest; an update replaces the one not
//   yet delivered. A receiver that takes late (a slow socket) gets the newest of each sender,
//   never a backlog. A receiver never gets its own updates, nor one it already got.
// - Payloads are opaque and shared (the same buffer goes to every receiver): the owner encodes
//   a notification once, and lazily (PresenceText): only an update some receiver takes is ever
//   encoded, so a sender faster than the interval costs no encoding for what is dropped.
// - Clients are known from join() to leave(); updates from an unknown sender are refused
//   (false) and change nothing; leave() drops the client's pending update with it.
// - Threading: every method takes the component's mutex, so the owner may call from any
//   thread; nothing is called out of it.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace marzipan::service {

// One update's text, made by `encode` on the first call of text() (from any thread, once), or
// given ready.
class PresenceText {
 public:
  explicit PresenceText(std::function<std::string()> encode) : encode_(std::move(encode)) {}
  explicit PresenceText(std::string text) : text_(std::make_shared<const std::string>(std::move(text))) {}

  const std::shared_ptr<const std::string>& text() const {
    std::call_once(once_, [this] {
      if (!text_) text_ = std::make_shared<const std::string>(encode_());
      encode_ = nullptr;
    });
    return text_;
  }

 private:
  mutable std::once_flag once_;
  mutable std::function<std::string()> encode_;
  mutable std::shared_ptr<const std::string> text_;
};

class PresenceCoalescer {
 public:
  using ClientId = std::uint64_t;
  using Clock = std::chrono::steady_clock;
  using Payload = std::shared_ptr<const PresenceText>;
  static constexpr std::chrono::milliseconds kDefaultInterval{50};

  struct Delivery {
    ClientId sender;
    std::uint64_t seq;  // the sender's update count when it was made (1, 2, ...)
    Payload payload;
  };

  explicit PresenceCoalescer(std::function<Clock::time_point()> now = Clock::now,
                             std::chrono::milliseconds interval = kDefaultInterval);

  void join(ClientId client);
  void leave(ClientId client);
  // The sender's newest presence; false (nothing kept) for a client not joined.
  bool update(ClientId sender, Payload payload);
  // The updates that may go to `receiver` now, one per sender, in sender order; marks them
  // delivered. Empty for a client not joined.
  std::vector<Delivery> take(ClientId receiver);
  // take() for every receiver at one instant (so that all of them are due again together one
  // interval later), in receiver order; receivers with nothing to take are left out.
  std::vector<std::pair<ClientId, std::vector<Delivery>>> takeAll();
  // When take(receiver) will next have something (already past: now), or nullopt when nothing
  // is pending for it.
  std::optional<Clock::time_point> nextDue(ClientId receiver) const;
  // The earliest nextDue over every receiver: when the owner's timer should fire.
  std::optional<Clock::time_point> nextDue() const;

  std::size_t clients() const;

 private:
  struct Sent {
    std::uint64_t seq = 0;     // the newest of the sender's updates the receiver got
    Clock::time_point at{};    // when
  };
  struct Client {
    std::uint64_t seq = 0;  // updates made
    Payload newest;
    std::unordered_map<ClientId, Sent> received;  // by sender
  };

  std::optional<Clock::time_point> dueLocked(ClientId receiver, const Client& r) const;
  std::vector<Delivery> takeLocked(ClientId receiver, Client& r, Clock::time_point now);

  std::function<Clock::time_point()> now_;
  std::chrono::milliseconds interval_;
  mutable std::mutex mutex_;
  std::unordered_map<ClientId, Client> clients_;
};

}  // namespace marzipan::service
