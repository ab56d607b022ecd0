// Presence between a session's clients (PROTOCOL.md, "Presence"): display names and colours,
// and the `presence` notifications forwarded through each session's PresenceCoalescer
// (service/presence.hpp) at most every 50 ms per sender and receiver, newest only.
//
// Conventions:
// - Threads: update() runs on the sender's pump and never touches the strand: it hands the
//   update, to be encoded on its first delivery (PresenceText), to the coalescer (its own
//   lock). Deliveries run on the session's strand (flush), so they are ordered with joins and
//   leaves, and a flush is a few microseconds between edits; they are armed on a timer for the
//   coalescer's nextDue, at least kFlushSpacing apart. Nothing is journaled or in the undo
//   history.
// - Cost: kFlushSpacing equals the coalescer's interval, so a busy session has one flush per
//   interval, and it carries every sender's newest update: each receiver gets them in one
//   hand-over (one batch for the network to write at once) instead of one every few
//   milliseconds. Each update is encoded once, when first taken, and shared by its receivers.
// - To a receiver each delivery is a transient text (ClientLink::sendTransient) keyed by the
//   sender: a congested connection holds at most the newest presence of each sender, and its
//   responses and splat deltas overtake them.
// - A client that leaves: the others get `presence {client, gone: true}` under the same key,
//   so it replaces any presence of that client still waiting for them.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <string>

#include "protocol/cpp/rpc.hpp"
#include "service/hub/connection.hpp"
#include "service/presence.hpp"

namespace marzipan::service {

struct HubCore;
struct LiveSession;

// One session's presence state (a member of LiveSession).
struct SessionPresence {
  PresenceCoalescer coalescer;
  std::mutex mutex;  // guards what follows
  bool flushScheduled = false;
  Clock::time_point lastFlush{};
};

class PresenceRelay {
 public:
  // Flushes of one session are at least this far apart: a presence waits at most this long
  // (plus the timer's lateness) before it goes, as with the coalescer's interval alone.
  static constexpr std::chrono::milliseconds kFlushSpacing = PresenceCoalescer::kDefaultInterval;
  // Colours given to a session's clients: the first one no member has, "#rrggbb".
  static constexpr std::size_t kPaletteSize = 16;
  static const char* const kPalette[kPaletteSize];

  explicit PresenceRelay(HubCore& hub) : hub_(hub) {}

  // On the strand, before c is added to s's clients: the palette colour fewest members have
  // (the first unused one while the session has at most kPaletteSize clients).
  static std::string colorFor(const LiveSession& s);
  // On the strand: c (admitted) may send and receive presence.
  void join(LiveSession& s, const HubClient& c);
  // On the strand: c leaves; its pending presence is dropped and the others hear it is gone.
  void leave(LiveSession& s, const HubClient& c);
  // On c's pump: c's newest presence (its brush dropped when c is a view client).
  void update(const std::shared_ptr<LiveSession>& s, const HubClient& c, const protocol::PresenceParams& p);

 private:
  void arm(const std::shared_ptr<LiveSession>& s, bool afterFlush);
  void flush(const std::shared_ptr<LiveSession>& s);
  HubCore& hub_;
};

}  // namespace marzipan::service
