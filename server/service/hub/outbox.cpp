// Outbox and HeldLink (see outbox.hpp).
#include "service/hub/outbox.hpp"

#include <algorithm>

namespace marzipan::service {

namespace {

// The messages one thread holds, by link in the order each link was first sent something.
struct Held {
  bool open = false;
  std::vector<std::pair<std::shared_ptr<ClientLink>, std::vector<ClientLink::Item>>> links;
};

thread_local Held tHeld;

}  // namespace

Outbox::Scope::Scope() : outer_(!tHeld.open) { tHeld.open = true; }

Outbox::Scope::~Scope() {
  if (!outer_) return;
  try {
    flush();
  } catch (...) {
    // A link that cannot take a message (out of memory) loses it, as a send outside the scope
    // would have thrown it away in the worker's task; the connection's next one still goes.
    tHeld.links.clear();
  }
  tHeld.open = false;
}

bool Outbox::holding() { return tHeld.open; }

void Outbox::hold(const std::shared_ptr<ClientLink>& link, ClientLink::Item item) {
  for (auto& [held, items] : tHeld.links) {
    if (held == link) {
      items.push_back(std::move(item));
      return;
    }
  }
  tHeld.links.emplace_back(link, std::vector<ClientLink::Item>{}).second.push_back(std::move(item));
}

void Outbox::flush() {
  if (tHeld.links.empty()) return;
  // Taken first: a link may send again from inside (a test's link, say), into a fresh list.
  auto links = std::move(tHeld.links);
  tHeld.links.clear();
  // Links that share a carrier are handed theirs in one call of it.
  std::vector<std::pair<ClientLink::Carrier*, std::vector<ClientLink::Delivery>>> carried;
  for (auto& [link, items] : links) {
    ClientLink::Carrier* const carrier = link->carrier();
    if (!carrier) {
      link->sendAll(std::move(items));
      continue;
    }
    auto at = std::find_if(carried.begin(), carried.end(), [&](const auto& c) { return c.first == carrier; });
    if (at == carried.end()) at = carried.insert(carried.end(), {carrier, {}});
    at->second.push_back({link, std::move(items)});
  }
  for (auto& [carrier, deliveries] : carried) carrier->carry(std::move(deliveries));
}

void HeldLink::sendText(std::string text) {
  if (!Outbox::holding()) return link_->sendText(std::move(text));
  Outbox::hold(link_, {std::make_shared<const std::string>(std::move(text)), nullptr});
}

void HeldLink::sendBinary(std::shared_ptr<const std::vector<std::uint8_t>> frame, bool latestWins) {
  if (!Outbox::holding()) return link_->sendBinary(std::move(frame), latestWins);
  Outbox::hold(link_, {nullptr, std::move(frame), latestWins});
}

void HeldLink::sendTransient(std::vector<Transient> texts) {
  if (!Outbox::holding()) return link_->sendTransient(std::move(texts));
  for (Transient& t : texts) Outbox::hold(link_, {std::move(t.text), nullptr, false, true, t.key});
}

void HeldLink::sendTogether(std::vector<Message> messages) {
  if (!Outbox::holding()) return link_->sendTogether(std::move(messages));
  for (Message& m : messages) Outbox::hold(link_, {std::move(m.text), std::move(m.binary)});
}

void HeldLink::sendAll(std::vector<Item> items) {
  if (!Outbox::holding()) return link_->sendAll(std::move(items));
  for (Item& i : items) Outbox::hold(link_, std::move(i));
}

void HeldLink::close(int code, std::string reason) {
  Outbox::flush();
  link_->close(code, std::move(reason));
}

}  // namespace marzipan::service
