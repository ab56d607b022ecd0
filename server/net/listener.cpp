// Listener (see listener.hpp): the acceptor, the connection bounds and the accept retry.
#include "net/listener.hpp"

#include <boost/asio/post.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core/bind_handler.hpp>

#include <chrono>
#include <stdexcept>
#include <string>
#include <utility>

#include "net/http_session.hpp"
#include "service/client_address.hpp"

namespace marzipan::net {

namespace {

std::string endpointText(const tcp::endpoint& ep) {
  const std::string address = ep.address().to_string();
  return (ep.address().is_v6() ? "[" + address + "]" : address) + ":" + std::to_string(ep.port());
}

}  // namespace

Listener::Listener(asio::io_context& ioc, const tcp::endpoint& endpoint, std::shared_ptr<SharedState> state)
    : ioc_(ioc), acceptor_(asio::make_strand(ioc)), state_(std::move(state)) {
  const std::string where = endpointText(endpoint);
  beast::error_code ec;
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
  port_ = acceptor_.local_endpoint().port();
}

void Listener::run() { doAccept(); }

void Listener::stop() {
  asio::post(acceptor_.get_executor(), [self = shared_from_this()] {
    self->close();
    self->state_->acceptorClosed();
  });
}

void Listener::close() {
  beast::error_code ignored;
  acceptor_.close(ignored);
  retry_.cancel();
}

void Listener::doAccept() {
  acceptor_.async_accept(asio::make_strand(ioc_), beast::bind_front_handler(&Listener::onAccept, shared_from_this()));
}

void Listener::onAccept(beast::error_code ec, tcp::socket socket) {
  if (ec == asio::error::operation_aborted) return;
  if (ec) {
    // Errors such as running out of file descriptors last a while: accepting again at once
    // would spin and flood the log, so wait a little first.
    state_->log("http: accept: " + ec.message());
    retry_.expires_after(std::chrono::milliseconds(100));
    retry_.async_wait([self = shared_from_this()](beast::error_code waited) {
      if (!waited && !self->state_->isStopping()) self->doAccept();
    });
    return;
  }
  // Responses, notifications and splat deltas are written back to back: Nagle's algorithm
  // would hold the later ones for the client's delayed ACK (about 40 ms per edit).
  beast::error_code noDelay;
  socket.set_option(tcp::no_delay(true), noDelay);
  beast::error_code remoteEc;
  const tcp::endpoint remote = socket.remote_endpoint(remoteEc);
  const std::string peer = remoteEc ? std::string("?") : endpointText(remote);
  if (auto slot = state_->takeSlot(remoteEc ? peer : service::addressLimitKey(remote.address().to_string()))) {
    std::make_shared<HttpSession>(std::move(socket), state_, peer, std::move(slot))->run();
  } else {
    state_->log("http: refused " + peer + ": too many connections (max_connections / max_connections_per_address)");
    beast::error_code ignored;
    socket.close(ignored);
  }
  if (!state_->isStopping()) doAccept();
}

}  // namespace marzipan::net
