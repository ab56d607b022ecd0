// HttpSession (see http_session.hpp): request routing, responses, and the WebSocket upgrade
// with its origin check.
#include "net/http_session.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/address.hpp>
#include <boost/beast/core/bind_handler.hpp>
#include <boost/beast/core/file.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/file_body.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>
#include <boost/beast/websocket/rfc6455.hpp>

#include <algorithm>
#include <cstdint>
#include <tuple>
#include <utility>

#include "net/static_files.hpp"
#include "net/websocket_session.hpp"

namespace marzipan::net {

namespace {

// The host name of a Host header ("name:port", "[v6]:port", "name"), without the port.
std::string_view hostName(std::string_view host) {
  if (!host.empty() && host.front() == '[') return host.substr(1, host.find(']') - 1);
  return host.substr(0, host.rfind(':'));
}

// Whether a page served under this Host is this server's own and not a DNS rebinding (a page
// of another site whose name now resolves to this address): an address literal, localhost, or
// a name of HttpServerOptions::publicHosts.
bool ownHost(const SharedState& state, std::string_view host) {
  const std::string name(hostName(host));
  if (name == "localhost") return true;
  beast::error_code ec;
  asio::ip::make_address(name, ec);
  if (!ec) return true;
  const auto& hosts = state.options.publicHosts;
  return std::find(hosts.begin(), hosts.end(), name) != hosts.end();
}

// Whether a browser's Origin may open a WebSocket here (see HttpServerOptions::allowedOrigins).
bool originAllowed(const SharedState& state, std::string_view origin, std::string_view host) {
  if (origin.empty()) return true;
  const auto& allowed = state.options.allowedOrigins;
  if (allowed.empty()) {
    const std::size_t scheme = origin.find("://");
    return scheme != std::string_view::npos && origin.substr(scheme + 3) == host && ownHost(state, host);
  }
  for (const std::string& a : allowed)
    if (a == "*" || a == origin) return true;
  return false;
}

}  // namespace

HttpSession::HttpSession(tcp::socket&& socket, std::shared_ptr<SharedState> state, std::string peer,
                         std::shared_ptr<void> slot)
    : stream_(std::move(socket)), state_(std::move(state)), peer_(std::move(peer)), slot_(std::move(slot)) {}

HttpSession::~HttpSession() {
  if (!joined_) return;
  state_->log("http: close " + peer_ + " after " + std::to_string(requests_) + " request(s)");
  state_->leave();
}

void HttpSession::run() {
  if (!state_->join(shared_from_this())) return;
  joined_ = true;
  state_->log("http: accept " + peer_);
  asio::dispatch(stream_.get_executor(), beast::bind_front_handler(&HttpSession::doRead, shared_from_this()));
}

void HttpSession::closeIfIdle() {
  asio::dispatch(stream_.get_executor(), [self = shared_from_this()] {
    if (!self->busy_ && !self->upgraded_) self->stream_.cancel();
  });
}

void HttpSession::doRead() {
  busy_ = false;
  if (state_->isStopping()) return;  // stop() ran before this read could be cancelled
  parser_.emplace();
  parser_->header_limit(static_cast<std::uint32_t>(state_->options.maxHeaderBytes));
  parser_->body_limit(state_->options.maxBodyBytes);
  stream_.expires_after(state_->options.idleTimeout);
  http::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&HttpSession::onRead, shared_from_this()));
}

void HttpSession::onRead(beast::error_code ec, std::size_t) {
  if (ec == http::error::header_limit) {
    return sendText(http::status::request_header_fields_too_large, false, "request header too large\n", false);
  }
  if (ec == http::error::body_limit) {
    return sendText(http::status::payload_too_large, false, "request body too large\n", false);
  }
  if (ec) return fail(ec, "read");
  busy_ = true;
  ++requests_;
  handle(parser_->release());
}

void HttpSession::handle(http::request<http::string_body>&& req) {
  const bool head = req.method() == http::verb::head;
  const bool keepAlive = req.keep_alive();
  const std::string_view target(req.target().data(), req.target().size());
  const std::string_view path = target.substr(0, target.find_first_of("?#"));
  const PathClass pathClass = path == "/healthz" ? PathClass::healthz
                              : path == "/metrics" ? PathClass::metrics
                              : path == "/ws"      ? PathClass::websocket
                                                   : PathClass::staticFile;
  state_->metrics.countRequest(pathClass);

  if (pathClass == PathClass::websocket && state_->options.hub && websocket::is_upgrade(req)) {
    const auto origin = req[http::field::origin];
    const auto host = req[http::field::host];
    if (!originAllowed(*state_, std::string_view(origin.data(), origin.size()), std::string_view(host.data(), host.size()))) {
      return sendText(http::status::forbidden, false, "WebSocket from origin not allowed\n", false);
    }
    busy_ = false;
    upgraded_ = true;
    std::make_shared<WsSession>(std::move(stream_), state_, peer_, std::move(slot_))->run(std::move(req));
    return;
  }
  if (req.method() != http::verb::get && !head) {
    return sendText(http::status::method_not_allowed, head, "method not allowed: GET and HEAD only\n", keepAlive);
  }
  switch (pathClass) {
    case PathClass::healthz: return sendText(http::status::ok, head, "ok", keepAlive);
    case PathClass::metrics:
      return sendText(http::status::ok, head, state_->metrics.renderPrometheus(), keepAlive,
                      "text/plain; version=0.0.4; charset=utf-8");
    case PathClass::websocket: return sendText(http::status::not_found, head, "not found\n", keepAlive);
    case PathClass::staticFile:
      for (const auto& [prefix, files] : state_->mounts) {
        if (path.size() > prefix.size() && path.compare(0, prefix.size(), prefix) == 0)
          return sendFile(files.resolve(target.substr(prefix.size() - 1)), head, keepAlive);
      }
      return sendFile(state_->files.resolve(target), head, keepAlive);
  }
}

void HttpSession::sendFile(const StaticFile& file, bool head, bool keepAlive) {
  if (file.status == StaticStatus::refused) return sendText(http::status::forbidden, head, "forbidden\n", keepAlive);
  if (file.status == StaticStatus::notFound) return sendText(http::status::not_found, head, "not found\n", keepAlive);
  http::file_body::value_type body;
  beast::error_code ec;
  body.open(file.path.c_str(), beast::file_mode::scan, ec);
  if (ec) return sendText(http::status::not_found, head, "not found\n", keepAlive);
  const std::uint64_t size = body.size();
  if (head) {
    http::response<http::empty_body> res{http::status::ok, 11};
    decorate(res, file.mimeType, keepAlive);
    res.content_length(size);
    return send(std::move(res));
  }
  http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(body)),
                                      std::make_tuple(http::status::ok, 11)};
  decorate(res, file.mimeType, keepAlive);
  res.content_length(size);
  send(std::move(res));
}

void HttpSession::sendText(http::status status, bool head, std::string text, bool keepAlive, std::string_view type) {
  if (static_cast<int>(status) >= 400) state_->metrics.countError(static_cast<int>(status));
  http::response<http::string_body> res{status, 11};
  decorate(res, type, keepAlive);
  if (status == http::status::method_not_allowed) res.set(http::field::allow, "GET, HEAD");
  res.content_length(text.size());
  if (!head) res.body() = std::move(text);
  send(std::move(res));
}

template <class Response>
void HttpSession::decorate(Response& res, std::string_view type, bool keepAlive) {
  res.set(http::field::server, "marzipan");
  res.set(http::field::content_type, beast::string_view(type.data(), type.size()));
  res.set(http::field::cache_control, "no-cache");
  res.set("X-Content-Type-Options", "nosniff");
  res.keep_alive(keepAlive && !state_->isStopping());
}

// One write in flight: the next read starts only after this one completes.
template <class Body>
void HttpSession::send(http::response<Body>&& res) {
  auto message = std::make_shared<http::response<Body>>(std::move(res));
  const bool close = !message->keep_alive();
  stream_.expires_after(state_->options.idleTimeout);
  http::async_write(stream_, *message,
                    [self = shared_from_this(), message, close](beast::error_code ec, std::size_t bytes) {
                      self->onWrite(close, ec, bytes);
                    });
}

void HttpSession::onWrite(bool close, beast::error_code ec, std::size_t bytes) {
  state_->metrics.addBytesSent(bytes);
  if (ec) return fail(ec, "write");
  if (close || state_->isStopping()) {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    return;
  }
  doRead();
}

void HttpSession::fail(beast::error_code ec, std::string_view what) {
  if (normalClose(ec)) return;
  state_->log("http: " + peer_ + " " + std::string(what) + ": " + ec.message());
}

}  // namespace marzipan::net
