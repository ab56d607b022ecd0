// HttpServer (see http_server.hpp): wires the pieces, as the main.cpp of Beast's chat-multi
// example does: an io_context run by options.threads I/O threads, the SharedState, the
// Listener, and the signal set. The pieces, one file each:
//   listener.hpp          accepts, applies the connection bounds, starts an HttpSession
//   http_session.hpp      one HTTP connection: reads requests, answers them; an upgrade at
//                         /ws becomes a WsSession, which takes over the socket
//   websocket_session.hpp one WebSocket: messages to the hub, the hub's answers through a Link
//                         (a ClientLink that holds the WsSession weakly and posts onto its strand)
//   shared_state.hpp      what they share: options, files, metrics, bounds, the live sessions
// Every session runs on its own strand and lives exactly as long as its pending operation;
// every failure goes through its `fail()`.
//
// Shutdown: stop() marks the state stopping, closes the acceptor, lets the hub finish running
// edits, closes every WebSocket with 1001 and cancels the read of every idle HTTP session; a
// session busy with a response finishes writing it, then closes.
#include "net/http_server.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>

#include <algorithm>
#include <condition_variable>
#include <csignal>
#include <exception>
#include <iostream>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "net/beast.hpp"
#include "net/http_session.hpp"
#include "net/listener.hpp"
#include "net/shared_state.hpp"
#include "net/websocket_session.hpp"
#include "service/hub.hpp"

namespace marzipan::net {

void logToStderr(const std::string& line) {
  static std::mutex stderrMutex;
  const std::lock_guard lock(stderrMutex);
  std::cerr << line << '\n';
}

struct HttpServer::Impl {
  explicit Impl(HttpServerOptions o) : options(std::move(o)), ioc(static_cast<int>(std::max(1u, options.threads))) {}

  HttpServerOptions options;
  Metrics metrics;  // before ioc: handlers destroyed with ioc may still count
  asio::io_context ioc;
  std::shared_ptr<SharedState> state;
  std::shared_ptr<Listener> listener;
  std::optional<asio::signal_set> signals;
  std::vector<std::thread> threads;
  std::mutex mutex;  // guards the two below
  std::condition_variable stopRequested;
  bool stopRequestedFlag = false, stopped = false;

  void requestStop() {
    const std::lock_guard lock(mutex);
    stopRequestedFlag = true;
    stopRequested.notify_all();
  }
};

HttpServer::HttpServer(HttpServerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

HttpServer::~HttpServer() { stop(); }

Metrics& HttpServer::metrics() { return impl_->metrics; }

void HttpServer::setHub(service::Hub* hub) {
  if (impl_->listener) throw std::logic_error("HttpServer::setHub after start");
  impl_->options.hub = hub;
}

void HttpServer::start() {
  Impl& s = *impl_;
  if (s.listener) throw std::logic_error("HttpServer::start called twice");
  beast::error_code ec;
  const asio::ip::address address = asio::ip::make_address(s.options.bind, ec);
  if (ec) throw std::runtime_error("not an IP address: \"" + s.options.bind + "\"");
  auto state = std::make_shared<SharedState>(s.options, s.metrics);
  s.listener = std::make_shared<Listener>(s.ioc, tcp::endpoint(address, s.options.port), state);
  s.state = std::move(state);
  if (s.options.handleSignals) {
    s.signals.emplace(s.ioc, SIGINT, SIGTERM);
    s.signals->async_wait([&s](beast::error_code sigEc, int signal) {
      if (sigEc) return;
      s.state->log("http: signal " + std::to_string(signal) + ", shutting down");
      s.requestStop();
    });
  }
  s.listener->run();
  const unsigned threads = std::max(1u, s.options.threads);
  for (unsigned i = 0; i < threads; ++i) {
    s.threads.emplace_back([&s] {
      for (;;) {
        try {
          s.ioc.run();
          return;
        } catch (const std::exception& e) {
          s.state->log(std::string("http: handler failed: ") + e.what());
        }
      }
    });
  }
}

std::uint16_t HttpServer::port() const { return impl_->listener ? impl_->listener->port() : 0; }

void HttpServer::waitForStopRequest() {
  std::unique_lock lock(impl_->mutex);
  impl_->stopRequested.wait(lock, [this] { return impl_->stopRequestedFlag; });
}

void HttpServer::stop() {
  Impl& s = *impl_;
  {
    const std::lock_guard lock(s.mutex);
    if (s.stopped) return;
    s.stopped = true;
    s.stopRequestedFlag = true;
    s.stopRequested.notify_all();
  }
  if (!s.state) return;
  const SharedState::Live live = s.state->startStopping();
  s.listener->stop();
  // Running edits finish and answer before their clients are told to go.
  if (s.options.hub) s.options.hub->shutdown();
  for (const auto& weak : live.websockets) {
    if (const auto ws = weak.lock()) ws->close(websocket::close_code::going_away, "server shutting down");
  }
  if (s.signals) {
    asio::post(s.ioc, [&s] {
      beast::error_code ignored;
      s.signals->cancel(ignored);
    });
  }
  for (const auto& weak : live.sessions) {
    if (const auto session = weak.lock()) session->closeIfIdle();
  }
  s.state->waitUntilIdle(s.options.shutdownGrace);
  s.ioc.stop();
  for (std::thread& t : s.threads) t.join();
  s.threads.clear();
  s.listener->close();  // in case the grace ran out before the posted close ran
}

}  // namespace marzipan::net
