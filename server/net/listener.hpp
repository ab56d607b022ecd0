// Accepts connections (chat-multi's `listener`): binds and listens in its constructor, then
// gives each accepted socket a strand of its own and a place under the connection bounds, and
// starts an HttpSession on it; a connection over a bound is closed at once.
//
// Conventions: owned by shared_ptr (HttpServer and its pending accept hold it). HttpServer
// makes it and calls run() before the I/O threads start; stop() posts onto the acceptor's
// strand, where the accepts run; close() runs there or once the I/O threads are joined. port()
// never changes after the constructor. An accept error (out of file descriptors, say) is
// retried after 100 ms rather than at once.
//
// Separate because it is the one piece that owns the acceptor: it needs Asio's socket and timer
// but none of Beast's HTTP or WebSocket operations.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include <cstdint>
#include <memory>

#include "net/beast.hpp"
#include "net/shared_state.hpp"

namespace marzipan::net {

class Listener : public std::enable_shared_from_this<Listener> {
 public:
  // Throws std::runtime_error naming the address and the cause when it cannot listen there.
  Listener(asio::io_context& ioc, const tcp::endpoint& endpoint, std::shared_ptr<SharedState> state);

  std::uint16_t port() const { return port_; }

  void run();
  // Closes the acceptor on its strand; SharedState::acceptorClosed tells when it is done.
  void stop();
  // On the acceptor's strand, or once no I/O thread runs.
  void close();

 private:
  void doAccept();
  void onAccept(beast::error_code ec, tcp::socket socket);

  asio::io_context& ioc_;
  tcp::acceptor acceptor_;
  asio::steady_timer retry_{acceptor_.get_executor()};  // on the acceptor's strand
  std::shared_ptr<SharedState> state_;
  std::uint16_t port_ = 0;
};

}  // namespace marzipan::net
