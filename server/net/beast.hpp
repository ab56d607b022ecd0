// The Boost names shared by the server's pieces (listener, http_session, websocket_session,
// after the beast.hpp and net.hpp of Beast's chat-multi example): the namespace aliases, and
// which errors end a connection the ordinary way.
//
// Conventions: internal to server/net. Only server/net's .cpp files and its internal headers
// (listener.hpp, http_session.hpp, websocket_session.hpp) include it; a header that code outside
// server/net includes (http_server.hpp and the like) never does, so Boost stays a PRIVATE
// dependency of marzipan_net. Only light Boost headers here: each piece includes the Beast
// parts it uses, since every Beast header costs seconds of compile time per file.
#pragma once

#include <boost/asio/error.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/websocket/error.hpp>

namespace marzipan::net {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

// The peer went away or stop() cancelled the operation: not worth a log line.
inline bool normalClose(const beast::error_code& ec) {
  return ec == asio::error::operation_aborted || ec == http::error::end_of_stream || ec == asio::error::eof ||
         ec == asio::error::connection_reset || ec == asio::error::broken_pipe;
}

}  // namespace marzipan::net
