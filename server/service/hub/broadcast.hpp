// What a session's clients hear without asking: session.changed and session.clients
// notifications, splat buffers (full, and deltas of the touched bricks), and the pushed frames
// of frames-mode clients.
//
// Conventions:
// - Everything here runs on the session's strand, except renders (on the workers, from a
//   snapshot). One edit sends the notification to every client first, then each client's delta
//   or frame; one delta buffer is shared by every splats-mode client.
// - Pushed frames are latest-wins: a client has at most one render running; changes meanwhile
//   ask for one more (renderAgain), and a still frame follows once nothing changed for
//   HubOptions::stillDelay.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/volume.hpp"
#include "protocol/cpp/frames.hpp"
#include "service/hub/connection.hpp"

namespace marzipan::service {

struct HubCore;
struct LiveSession;

SharedBytes makeFrame(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                      std::span<const std::uint8_t> payload);

class Broadcaster {
 public:
  explicit Broadcaster(HubCore& hub) : hub_(hub) {}

  // After a change by `by`: the notification, then each client's delta (or full buffer when
  // `full`) or frame.
  void changed(LiveSession& s, const HubClient& by, std::string_view cause, const Box& roi,
               const std::vector<Int3>& bricks, bool full);
  // The clients of s, as session.create/join/stats and session.clients list them.
  static nlohmann::json clientList(const LiveSession& s);
  // session.clients with `list` to every client of s but `except`.
  void clients(LiveSession& s, const HubClient* except, const nlohmann::json& list);

  // Every splat of vol in one frame; counts its bricks and points when asked.
  SharedBytes fullSplatsFrame(const Volume& vol, std::uint32_t requestId, std::uint64_t revision,
                              std::size_t* bricks, std::size_t* points);
  void sendFullSplats(LiveSession& s, HubClient& c, std::uint32_t requestId);
  // A pushed frame for a frames-mode client, latest wins.
  void requestFrame(LiveSession& s, const std::shared_ptr<HubClient>& c);

 private:
  void startRender(LiveSession& s, const std::shared_ptr<HubClient>& c, bool still);
  HubCore& hub_;
};

}  // namespace marzipan::service
