// The socket side of `marzipan serve`: one port, GET/HEAD only, static files of the web root at
// "/" (and of each mount under its prefix), "/healthz" (200 "ok"), "/metrics" (Prometheus
// text), and WebSocket upgrades at "/ws", whose messages go to a service::Hub (404 without
// one). A narrow, Beast-free interface: Boost.Beast/Asio stay inside server/net's .cpp files
// and its internal headers (listener, http_session, websocket_session; http_server.cpp lists
// them), so including this header costs nothing.
//
// WebSocket conventions: one read loop and one write in flight per connection; the outgoing
// queue keeps responses and splat buffers in order and replaces a queued pushed image by a
// newer one; a connection whose undelivered non-droppable bytes exceed the hub's
// maxQueuedBytes is closed with 1008 "too far behind" (one message counts at most half the
// bound: the bound is for backlog, a single big answer always goes out). Transient texts
// (presence) wait behind everything else, the newest per key only. What is queued when the
// socket is free leaves as one gathered write of whole frames (ws_socket.hpp), so a batch of
// transients, or messages handed over together (a change's response, notification and splat
// delta, ClientLink::sendAll), leave in one TCP push. Text over maxTextBytes closes with 1009,
// invalid UTF-8 with 1007, an unreadable binary frame or one of another kind than 9 with 1008.
// Pings every ping period; no answer within two closes the connection.
//
// Conventions: one log line per connection event (accept, close, error, signal) goes to
// HttpServerOptions::log, stderr when unset. Refused paths answer 403, missing files 404,
// other methods 405 with "Allow: GET, HEAD", oversized requests 431/413 and close.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "net/metrics.hpp"

namespace marzipan::service {
class Hub;
}

namespace marzipan::net {

struct HttpServerOptions {
  std::string bind = "127.0.0.1";        // an IPv4 or IPv6 address literal
  std::uint16_t port = 8080;             // 0 = let the system pick a free port (see HttpServer::port)
  std::filesystem::path webRoot;         // must be a directory
  unsigned threads = 1;                  // I/O threads, at least 1
  std::size_t maxHeaderBytes = 16 * 1024;  // request line + headers; larger → 431
  std::size_t maxBodyBytes = 64 * 1024;    // request body (read and ignored); larger → 413
  std::chrono::milliseconds idleTimeout{30'000};    // a connection silent this long is closed
  std::chrono::milliseconds shutdownGrace{5'000};   // stop() waits this long for requests in flight
  bool handleSignals = false;            // SIGINT/SIGTERM wake waitForStopRequest()
  // Further static directories: URL prefix ("/protocol/js/", with both slashes) -> directory.
  std::vector<std::pair<std::string, std::filesystem::path>> mounts;
  // Where /ws messages go; not owned, must outlive the server. Null: /ws answers 404.
  service::Hub* hub = nullptr;
  // Origins ("http://host:port") a browser may open /ws from; empty: only the page's own
  // (Origin's host equal to the Host header); "*": any. Requests without Origin (scripts) pass.
  std::vector<std::string> allowedOrigins;
  // Host names (without port) under which browsers reach this server, for the page's-own check
  // above: there the Host must also be an address literal, localhost or one of these, so that
  // a page of another site whose name was rebound to this address cannot drive it.
  std::vector<std::string> publicHosts;
  std::function<void(const std::string&)> log;  // one line, no newline; called from I/O threads
};

// Writes one line (no newline) to stderr under the process's one logging lock, so that lines of
// the server and of the hub never interleave. HttpServerOptions::log defaults to it.
void logToStderr(const std::string& line);

class HttpServer {
 public:
  explicit HttpServer(HttpServerOptions options);
  ~HttpServer();  // stop()
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Binds, listens and starts the I/O threads. Throws std::runtime_error naming the cause (web
  // root missing, address invalid or in use); call at most once.
  void start();
  // The port it listens on, the chosen one when options.port was 0; valid after start().
  std::uint16_t port() const;
  // Blocks until SIGINT/SIGTERM arrives (with options.handleSignals) or stop() is called.
  void waitForStopRequest();
  // Stops accepting, lets the hub finish running edits (Hub::shutdown), closes WebSockets with
  // 1001 and idle connections, lets requests in flight finish (at most options.shutdownGrace),
  // then joins the I/O threads. Idempotent; not from a handler.
  void stop();

  Metrics& metrics();
  // Sets options.hub before start() (a hub wired to metrics() is made after the server).
  void setHub(service::Hub* hub);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace marzipan::net
