#include "service/hub/presence_relay.hpp"

#include <algorithm>
#include <array>

#include "service/hub/core.hpp"

namespace marzipan::service {

using nlohmann::json;

// Sasha Trubetskoy's list of distinct colours, without white, black and greys: readable as a
// ring on the clay model and as text on the page.
const char* const PresenceRelay::kPalette[kPaletteSize] = {
    "#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4", "#f032e6", "#bfef45",
    "#fabed4", "#469990", "#dcbeff", "#9a6324", "#fffac8", "#800000", "#aaffc3", "#000075"};

std::string PresenceRelay::colorFor(const LiveSession& s) {
  std::array<int, kPaletteSize> used{};
  for (const auto& c : s.members())
    for (std::size_t i = 0; i < kPaletteSize; ++i)
      if (c->color == kPalette[i]) ++used[i];
  return kPalette[std::size_t(std::min_element(used.begin(), used.end()) - used.begin())];
}

void PresenceRelay::join(LiveSession& s, const HubClient& c) { s.presence.coalescer.join(PresenceCoalescer::ClientId(c.clientId)); }

void PresenceRelay::leave(LiveSession& s, const HubClient& c) {
  s.presence.coalescer.leave(PresenceCoalescer::ClientId(c.clientId));
  const auto gone =
      std::make_shared<const std::string>(protocol::notificationText("presence", {{"client", c.clientId}, {"gone", true}}));
  for (const auto& other : s.members())
    if (other.get() != &c) other->link->sendTransient({{gone, std::uint64_t(c.clientId)}});
}

void PresenceRelay::update(const std::shared_ptr<LiveSession>& s, const HubClient& c, const protocol::PresenceParams& p) {
  // Encoded on its first delivery (flush), if any: most updates of a 60 Hz sender are replaced
  // before they are due.
  auto text = std::make_shared<const PresenceText>(
      [id = c.clientId, name = c.name, color = c.color, brush = c.readOnly ? std::nullopt : p.brush, camera = p.camera] {
        json params = {{"client", id}, {"name", name}, {"color", color}};
        if (brush) params["brush"] = protocol::brushJson(*brush);
        if (camera) params["camera"] = protocol::cameraJson(*camera);
        return protocol::notificationText("presence", params);
      });
  if (!s->presence.coalescer.update(PresenceCoalescer::ClientId(c.clientId), std::move(text))) return;
  arm(s, false);
}

void PresenceRelay::arm(const std::shared_ptr<LiveSession>& s, bool afterFlush) {
  Clock::time_point at;
  {
    const std::lock_guard lock(s->presence.mutex);
    if (afterFlush) s->presence.flushScheduled = false;
    if (s->presence.flushScheduled) return;
    const auto due = s->presence.coalescer.nextDue();
    if (!due) return;
    s->presence.flushScheduled = true;
    at = std::max(*due, s->presence.lastFlush + kFlushSpacing);
  }
  const auto wait = std::chrono::ceil<std::chrono::milliseconds>(at - Clock::now());
  auto run = [self = hub_.shared_from_this(), weak = std::weak_ptr<LiveSession>(s)] {
    if (const auto live = weak.lock()) live->strand->post([self, live] { self->presence.flush(live); });
  };
  if (wait.count() <= 0) run();
  else hub_.workers.postAfter(wait, std::move(run));
}

void PresenceRelay::flush(const std::shared_ptr<LiveSession>& s) {
  {
    const std::lock_guard lock(s->presence.mutex);
    s->presence.lastFlush = Clock::now();
  }
  if (s->unloaded || !s->session) {
    const std::lock_guard lock(s->presence.mutex);
    s->presence.flushScheduled = false;
    return;
  }
  // Every receiver's share at one instant: one batch each, all due again together.
  auto taken = s->presence.coalescer.takeAll();
  try {
    for (const auto& c : s->members()) {
      const auto mine = std::lower_bound(taken.begin(), taken.end(), PresenceCoalescer::ClientId(c->clientId),
                                         [](const auto& t, PresenceCoalescer::ClientId id) { return t.first < id; });
      if (mine == taken.end() || mine->first != PresenceCoalescer::ClientId(c->clientId)) continue;
      std::vector<ClientLink::Transient> batch;
      batch.reserve(mine->second.size());
      for (const PresenceCoalescer::Delivery& d : mine->second) batch.push_back({d.payload->text(), d.sender});
      c->link->sendTransient(std::move(batch));
    }
  } catch (const std::exception& e) {
    // Encoding checked values cannot fail; should it, this flush is lost, not the next ones.
    if (hub_.options.events.log) hub_.options.events.log(std::string("presence: flush failed: ") + e.what());
  }
  arm(s, true);
}

}  // namespace marzipan::service
