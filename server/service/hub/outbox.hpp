// What a piece of the hub's work sends, held on its thread and handed to each link as one
// (ClientLink::sendAll) when the work lets its connection go on, instead of message by message.
// A stroke's application sends its requester the response and then, like every client of the
// session, the change's notification and splat delta: held, that is one hand-over per client
// (one TCP push) where it was two or three, and the clients' hand-overs go to the network thread
// together (one post through the links' ClientLink::Carrier, not one per client). Pinned to one
// core, each post to the network thread was a wake-up and a switch between the threads
// (docs/benchmark-log.md, capacity).
//
// Conventions:
// - Threads: an Outbox::Scope holds the sends of the thread it was opened on (thread-local; a
//   scope opened inside another adds to the outer one). Links are handed what they were sent in
//   order, each link its own messages; messages to different links have no order between them.
// - What sends from a strand task holds is flushed before the task lets the connection's next
//   message start (HubCore::finish) and when the scope closes, so a connection's answers still
//   come in request order; a close, and a long operation's op.progress, flush first.
// - Flushing calls the links with nothing of the hub's locked: each link's sendAll, or, for links
//   that share a carrier (ClientLink::carrier), one carry() with all of theirs.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "service/hub.hpp"

namespace marzipan::service {

class Outbox {
 public:
  // Holds this thread's sends until it is closed (unless a scope is open already).
  class Scope {
   public:
    Scope();
    ~Scope();  // flushes (what a failed flush could not hand over is lost)
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    bool outer_;
  };

  // Whether this thread holds its sends.
  static bool holding();
  // Holds `item` for `link` (holding() must be true).
  static void hold(const std::shared_ptr<ClientLink>& link, ClientLink::Item item);
  // Hands every held message to its link, in order; nothing when this thread holds none.
  static void flush();
};

// The link the hub gives a connection: the network's link, through this thread's Outbox when
// one is open.
class HeldLink final : public ClientLink {
 public:
  explicit HeldLink(std::shared_ptr<ClientLink> link) : link_(std::move(link)) {}
  void sendText(std::string text) override;
  void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>> frame, bool latestWins) override;
  void sendTransient(std::vector<Transient> texts) override;
  void sendTogether(std::vector<Message> messages) override;
  void sendAll(std::vector<Item> items) override;
  void close(int code, std::string reason) override;

 private:
  const std::shared_ptr<ClientLink> link_;
};

}  // namespace marzipan::service
