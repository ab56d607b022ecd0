// One HTTP connection (chat-multi's `http_session`): reads a request, answers it, reads the
// next (keep-alive). It serves /healthz, /metrics and the static files, refuses what
// http_server.hpp says it refuses, and turns a GET /ws with an upgrade from an allowed origin
// into a WsSession, handing over its socket and its connection slot.
//
// Conventions: made and run() by the Listener, on the acceptor's strand, for a socket that has
// a strand of its own; all the rest runs on the socket's strand (closeIfIdle, from stop(),
// dispatches onto it). Owned by shared_ptr and alive as long as an operation is pending on it.
// One request at a time: the next read starts once the response is written. A read or a write
// waits at most options.idleTimeout.
//
// Separate because it is the HTTP half of the Beast code: the parser and the response writes
// are instantiated in http_session.cpp alone; the listener and http_server.cpp parse only this
// header, which has no WebSocket in it.
#pragma once

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "net/beast.hpp"
#include "net/shared_state.hpp"

namespace marzipan::net {

struct StaticFile;

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  // `slot`: the connection's place under the connection bounds, released with the session (or
  // handed on to the WsSession it becomes).
  HttpSession(tcp::socket&& socket, std::shared_ptr<SharedState> state, std::string peer, std::shared_ptr<void> slot);
  ~HttpSession();  // leaves the registry

  // Starts reading unless the server is stopping (then the connection is dropped).
  void run();
  // From stop(), any thread: ends the session now unless a response is on its way.
  void closeIfIdle();

 private:
  void doRead();
  void onRead(beast::error_code ec, std::size_t);
  void handle(http::request<http::string_body>&& req);
  void sendFile(const StaticFile& file, bool head, bool keepAlive);
  void sendText(http::status status, bool head, std::string text, bool keepAlive,
                std::string_view type = "text/plain; charset=utf-8");
  template <class Response>
  void decorate(Response& res, std::string_view type, bool keepAlive);
  template <class Body>
  void send(http::response<Body>&& res);
  void onWrite(bool close, beast::error_code ec, std::size_t bytes);
  void fail(beast::error_code ec, std::string_view what);

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<SharedState> state_;
  std::string peer_;
  std::shared_ptr<void> slot_;  // this connection's place under the connection bounds
  bool joined_ = false;  // counted in the shared state's live sessions
  bool busy_ = false;  // a request has been read and its response not yet written
  bool upgraded_ = false;  // the socket went to a WsSession
  std::size_t requests_ = 0;
};

}  // namespace marzipan::net
