// Presence coalescing (see presence.hpp).
#include "service/presence.hpp"

#include <algorithm>
#include <utility>

namespace marzipan::service {

PresenceCoalescer::PresenceCoalescer(std::function<Clock::time_point()> now, std::chrono::milliseconds interval)
    : now_(std::move(now)), interval_(interval) {}

void PresenceCoalescer::join(ClientId client) {
  const std::lock_guard lock(mutex_);
  clients_.try_emplace(client);
}

void PresenceCoalescer::leave(ClientId client) {
  const std::lock_guard lock(mutex_);
  clients_.erase(client);
  for (auto& [id, c] : clients_) c.received.erase(client);
}

bool PresenceCoalescer::update(ClientId sender, Payload payload) {
  const std::lock_guard lock(mutex_);
  const auto it = clients_.find(sender);
  if (it == clients_.end()) return false;
  ++it->second.seq;
  it->second.newest = std::move(payload);
  return true;
}

std::vector<PresenceCoalescer::Delivery> PresenceCoalescer::take(ClientId receiver) {
  const Clock::time_point now = now_();
  const std::lock_guard lock(mutex_);
  const auto r = clients_.find(receiver);
  if (r == clients_.end()) return {};
  return takeLocked(receiver, r->second, now);
}

std::vector<std::pair<PresenceCoalescer::ClientId, std::vector<PresenceCoalescer::Delivery>>> PresenceCoalescer::takeAll() {
  const Clock::time_point now = now_();
  const std::lock_guard lock(mutex_);
  std::vector<std::pair<ClientId, std::vector<Delivery>>> out;
  for (auto& [id, c] : clients_)
    if (auto d = takeLocked(id, c, now); !d.empty()) out.emplace_back(id, std::move(d));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

std::vector<PresenceCoalescer::Delivery> PresenceCoalescer::takeLocked(ClientId receiver, Client& r, Clock::time_point now) {
  std::vector<Delivery> out;
  for (const auto& [sender, s] : clients_) {
    if (sender == receiver || s.seq == 0) continue;
    const auto got = r.received.find(sender);
    if (got != r.received.end() && (got->second.seq == s.seq || now < got->second.at + interval_)) continue;
    r.received[sender] = {s.seq, now};
    out.push_back({sender, s.seq, s.newest});
  }
  std::sort(out.begin(), out.end(), [](const Delivery& a, const Delivery& b) { return a.sender < b.sender; });
  return out;
}

std::optional<PresenceCoalescer::Clock::time_point> PresenceCoalescer::dueLocked(ClientId receiver,
                                                                                 const Client& r) const {
  std::optional<Clock::time_point> due;
  for (const auto& [sender, s] : clients_) {
    if (sender == receiver || s.seq == 0) continue;
    const auto got = r.received.find(sender);
    if (got != r.received.end() && got->second.seq == s.seq) continue;
    // Never delivered: due since the epoch of the clock, i.e. now.
    const Clock::time_point at = got == r.received.end() ? Clock::time_point{} : got->second.at + interval_;
    if (!due || at < *due) due = at;
  }
  return due;
}

std::optional<PresenceCoalescer::Clock::time_point> PresenceCoalescer::nextDue(ClientId receiver) const {
  const std::lock_guard lock(mutex_);
  const auto r = clients_.find(receiver);
  if (r == clients_.end()) return std::nullopt;
  return dueLocked(receiver, r->second);
}

std::optional<PresenceCoalescer::Clock::time_point> PresenceCoalescer::nextDue() const {
  const std::lock_guard lock(mutex_);
  std::optional<Clock::time_point> due;
  for (const auto& [id, c] : clients_)
    if (const auto d = dueLocked(id, c); d && (!due || *d < *due)) due = d;
  return due;
}

std::size_t PresenceCoalescer::clients() const {
  const std::lock_guard lock(mutex_);
  return clients_.size();
}

}  // namespace marzipan::service
