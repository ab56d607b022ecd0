// What the listener and every session share (chat-multi's `shared_state`): the options, the
// static file trees, the metrics, the connection bounds (HubLimits::maxConnections and
// maxConnectionsPerAddress), and the registry of live sessions that HttpServer::stop() closes.
//
// Conventions: owned by shared_ptr; HttpServer, the listener, each session and each connection
// slot hold one, so it outlives the last of them whichever ends first. `options` and `metrics`
// belong to HttpServer, which outlives every session (stop() joins the I/O threads). Any thread
// may call any member: each takes `mutex_` for what it touches and calls nothing outside while
// holding it (the hub's limits are read before locking). Sessions are registered by weak_ptr,
// so the registry never keeps a connection alive.
//
// Separate and Beast-free (the sessions are only declared here) because every other piece
// includes it: it costs them no Boost parse, and shared_state.cpp compiles without Boost.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "net/http_server.hpp"
#include "net/static_files.hpp"

namespace marzipan::net {

class HttpSession;
class WsSession;

class SharedState : public std::enable_shared_from_this<SharedState> {
 public:
  // `options` and `metrics` must outlive this (see above); throws when a web root or mount is
  // not a directory.
  SharedState(const HttpServerOptions& options, Metrics& metrics);

  // One line to options.log, stderr when unset.
  void log(const std::string& line) const;

  // Registers a new HTTP session; false once stopping (the caller drops the connection).
  bool join(const std::shared_ptr<HttpSession>& session);
  void leave();
  // Registers a WebSocket for the 1001 close at shutdown; false once stopping.
  bool joinWs(const std::shared_ptr<WsSession>& ws);
  void leaveWs();
  bool isStopping();

  // A TCP connection's place under the connection bounds, for the address key
  // service::addressLimitKey gives; released when the last holder (the HTTP session, then the
  // WebSocket session) lets it go. Null when a bound is reached: the caller closes the socket.
  std::shared_ptr<void> takeSlot(const std::string& address);

  // The sessions alive when the server started stopping; from then on join and joinWs refuse.
  struct Live {
    std::vector<std::weak_ptr<HttpSession>> sessions;
    std::vector<std::weak_ptr<WsSession>> websockets;
  };
  Live startStopping();
  // The listener's acceptor is closed (from its strand).
  void acceptorClosed();
  // Blocks until every session has ended and the acceptor is closed, or `grace` has passed.
  void waitUntilIdle(std::chrono::milliseconds grace);

  const HttpServerOptions& options;
  const StaticFiles files;
  std::vector<std::pair<std::string, StaticFiles>> mounts;  // URL prefix -> its files
  Metrics& metrics;

 private:
  std::mutex mutex_;  // guards the nine below
  std::condition_variable idle_;  // notified when live_ drops to 0 and when the acceptor closed
  bool stopping_ = false, acceptorClosed_ = false;
  std::vector<std::weak_ptr<HttpSession>> sessions_;
  std::vector<std::weak_ptr<WsSession>> websockets_;
  std::size_t live_ = 0;  // HTTP sessions and WebSockets
  std::size_t liveWs_ = 0;
  std::size_t connections_ = 0;                    // slots taken
  std::map<std::string, std::size_t> perAddress_;  // slots taken per addressLimitKey
};

}  // namespace marzipan::net
