// A WebSocket connection (chat-multi's `websocket_session`): reads whole messages into the hub
// and writes what the hub sends, with the queue, limits and close codes that http_server.hpp
// describes. After a message larger than max_text_bytes (an upload) the read buffer is given
// back, so a connection does not keep an upload's size resident (issue 31).
//
// Conventions: made by an HttpSession from a GET /ws with an upgrade, which hands over its
// stream and its connection slot. Owned by shared_ptr and alive as long as an operation is
// pending on it; the hub holds it only weakly, through a Link (a service::ClientLink). Its
// state is touched on the connection's strand only: send, sendTogether, sendTransient and close
// may be called from any thread and dispatch onto the strand; the rest runs on it.
//
// Writes: what is queued when the socket is free leaves as one gathered write of whole frames
// (WsSession frames its data messages itself, ws_socket.hpp), at most kMaxBatch messages: a
// hand-over's messages (sendTogether, sendAll) are queued together and so leave in one TCP push,
// as does a batch of transients, and nothing waits for what comes after it.
//
// Order: whatever the hub hands one connection reaches its strand by one of two ways, its own
// dispatch or a carrier's post onto another connection's strand and from there onward, so two
// hand-overs could arrive in the other order than they were made (another sculptor's revision
// r + 1 before r). Each hand-over (send, sendTogether, sendTransient, sendAll, close, a carry)
// takes a ticket where it is made, and the strand applies them in ticket order: one that comes
// early waits, with its items, until those before it have come.
//
// Separate from the HTTP session because it is the other half of the Beast code: the WebSocket
// stream's operations are instantiated in websocket_session.cpp alone; http_session.cpp (which
// makes it) and http_server.cpp (which closes it at shutdown) only parse this header.
#pragma once

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/websocket/stream.hpp>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "net/beast.hpp"
#include "net/shared_state.hpp"
#include "net/ws_socket.hpp"
#include "service/hub.hpp"

namespace marzipan::net {

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  // `slot`: the connection's place under the connection bounds, released with the session.
  WsSession(beast::tcp_stream&& stream, std::shared_ptr<SharedState> state, std::string peer, std::shared_ptr<void> slot);
  ~WsSession();  // disconnects from the hub, leaves the registry

  // Accepts the upgrade `req` asked for, unless the server is stopping (then it drops it).
  void run(http::request<http::string_body> req);

  // From any thread: queue a message (see the write conventions in http_server.hpp).
  void send(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
            bool latestWins);
  // Messages handed over together (ClientLink::sendTogether): queued at once, in order, so
  // that they leave in one TCP push.
  void sendTogether(std::vector<service::ClientLink::Message> messages);
  // Transient texts (ClientLink::sendTransient), handed over at once and written as one batch.
  void sendTransient(std::vector<service::ClientLink::Transient> texts);
  // What one piece of the hub's work sent (ClientLink::sendAll), queued at once, in order.
  void sendAll(std::vector<service::ClientLink::Item> items);
  void close(websocket::close_code code, std::string reason);

 private:
  // The next ticket (see Order above): taken in the caller's thread, in the order of the calls.
  std::uint64_t takeTicket() { return tickets_.fetch_add(1, std::memory_order_relaxed); }
  // On the strand: runs `apply` in its ticket's turn, now or once the tickets before it came.
  template <class Apply>
  void inTurn(std::uint64_t ticket, Apply&& apply);
  void runEarly();  // what waited for the turns now reached
  // sendAll with its ticket already taken (a carrier takes it when it is handed the items).
  void deliver(std::uint64_t ticket, std::vector<service::ClientLink::Item> items);

  class Link;     // the hub's view of this connection
  class Carrier;  // hands several connections their messages in one post (ClientLink::Carrier)

  struct Out {
    std::shared_ptr<const std::string> text;
    std::shared_ptr<const std::vector<std::uint8_t>> binary;
    bool latestWins = false;
    std::size_t charge = 0;  // what it counts against maxQueuedBytes (non-droppable only)
    bool transient = false;  // presence: replaced by its key, overtaken by everything else
    std::uint64_t key = 0;
    std::array<std::uint8_t, 10> header{};  // its frame header, made when it is written
    std::size_t size() const { return text ? text->size() : binary->size(); }
  };

  void onAccept(beast::error_code ec);
  void doRead();
  void onRead(beast::error_code ec, std::size_t bytes);
  std::uint64_t announcedUpload(const std::string& text, const service::HubLimits& limits) const;
  // Queue a message; the caller starts the write (write()) once its hand-over is queued.
  void enqueue(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
               bool latestWins);
  void enqueueTransient(std::shared_ptr<const std::string> text, std::uint64_t key);
  void write();  // starts a write of what is queued, unless one is in flight
  void doWrite();
  void onWrite(beast::error_code ec, std::size_t bytes);
  void startClose(websocket::close_code code, std::string reason);
  void doClose();
  void fail(beast::error_code ec, std::string_view what);

  websocket::stream<WsSocket> ws_;
  beast::flat_buffer buffer_;
  std::shared_ptr<SharedState> state_;
  std::string peer_;
  std::shared_ptr<void> slot_;  // this connection's place under the connection bounds
  std::size_t nextReadMax_ = 0;  // the largest next message: max_text_bytes, or an announced upload
  std::shared_ptr<service::HubClient> client_;
  std::deque<Out> queue_;        // waiting to be written
  std::vector<Out> writing_;     // in flight: one gathered write (unchanged until it completes)
  std::size_t queuedBytes_ = 0;  // the charges of what is queued, those in flight included
  std::atomic<std::uint64_t> tickets_{0};
  std::uint64_t turn_ = 0;                                 // on the strand: the ticket applied next
  std::map<std::uint64_t, std::function<void()>> early_;   // on the strand: hand-overs before their turn
  bool closing_ = false, closeAfterWrite_ = false, joined_ = false;
  websocket::close_reason closeReason_;
  std::string closeReasonText_;
};

}  // namespace marzipan::net
