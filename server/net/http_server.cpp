// Listener and HTTP sessions on Boost.Beast, after Beast's chat-multi example: a `Listener`
// accepts, one `HttpSession` per connection reads a request, answers it and reads the next
// (keep-alive), and `SharedState` is what they share. Every session runs on its own strand and
// lives exactly as long as its pending operation; every failure goes through `fail()`.
//
// A GET of /ws with an upgrade becomes a `WsSession`: the HTTP session hands over its socket.
// A WsSession reads whole messages and gives them to the hub; the hub answers through a `Link`
// (a ClientLink that holds the WsSession weakly and posts onto its strand).
//
// Shutdown: stop() marks the state stopping, closes the acceptor, lets the hub finish running
// edits, closes every WebSocket with 1001 and cancels the read of every idle HTTP session; a
// session busy with a response finishes writing it, then closes.
#include "net/http_server.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <exception>
#include <iostream>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "net/static_files.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/rpc.hpp"
#include "service/client_address.hpp"
#include "service/hub.hpp"

namespace marzipan::net {

void logToStderr(const std::string& line) {
  static std::mutex stderrMutex;
  const std::lock_guard lock(stderrMutex);
  std::cerr << line << '\n';
}

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

namespace {

// The largest text read for the upload it announces: a volume.load
// ({"jsonrpc","id","method","params":{"bytes","format"}}) is under 200 bytes as clients write it.
constexpr std::size_t kMaxVolumeLoadBytes = 4 * 1024;

class HttpSession;
class WsSession;

std::string endpointText(const tcp::endpoint& ep) {
  const std::string address = ep.address().to_string();
  return (ep.address().is_v6() ? "[" + address + "]" : address) + ":" + std::to_string(ep.port());
}

// What the listener and the sessions share.
struct SharedState : std::enable_shared_from_this<SharedState> {
  SharedState(const HttpServerOptions& o, Metrics& m) : options(o), files(o.webRoot), metrics(m) {
    for (const auto& [prefix, dir] : o.mounts) mounts.emplace_back(prefix, StaticFiles(dir));
  }

  void log(const std::string& line) const {
    if (options.log) return options.log(line);
    logToStderr(line);
  }

  // Registers a new session; false once stopping (the caller drops the connection).
  bool join(const std::shared_ptr<HttpSession>& session) {
    const std::lock_guard lock(mutex);
    if (stopping) return false;
    if (sessions.size() >= 2 * live + 64) std::erase_if(sessions, [](const auto& w) { return w.expired(); });
    sessions.push_back(session);
    ++live;
    return true;
  }

  void leave() {
    const std::lock_guard lock(mutex);
    --live;
    if (live == 0) idle.notify_all();
  }

  bool isStopping() {
    const std::lock_guard lock(mutex);
    return stopping;
  }

  // Registers a WebSocket for the 1001 close at shutdown; false once stopping.
  bool joinWs(const std::shared_ptr<WsSession>& ws) {
    const std::lock_guard lock(mutex);
    if (stopping) return false;
    if (websockets.size() >= 2 * liveWs + 64) std::erase_if(websockets, [](const auto& w) { return w.expired(); });
    websockets.push_back(ws);
    ++liveWs;
    ++live;
    return true;
  }

  void leaveWs() {
    const std::lock_guard lock(mutex);
    --liveWs;
    --live;
    if (live == 0) idle.notify_all();
  }

  // A TCP connection's place under the connection bounds (HubLimits::maxConnections and
  // maxConnectionsPerAddress); released when the last holder (HTTP, then WebSocket session)
  // goes. Null when a bound is reached: the caller closes the socket.
  std::shared_ptr<void> takeSlot(const std::string& address) {
    const service::HubLimits limits = options.hub ? options.hub->limits() : service::HubLimits{};
    {
      const std::lock_guard lock(mutex);
      std::size_t& mine = perAddress[address];
      if (connections >= limits.maxConnections || mine >= limits.maxConnectionsPerAddress) {
        if (mine == 0) perAddress.erase(address);
        return nullptr;
      }
      ++mine;
      ++connections;
    }
    return std::shared_ptr<void>(new char, [self = shared_from_this(), address](void* p) {
      delete static_cast<char*>(p);
      const std::lock_guard lock(self->mutex);
      --self->connections;
      if (--self->perAddress[address] == 0) self->perAddress.erase(address);
    });
  }

  const HttpServerOptions& options;
  const StaticFiles files;
  std::vector<std::pair<std::string, StaticFiles>> mounts;
  Metrics& metrics;
  std::mutex mutex;  // guards the nine below
  std::condition_variable idle;  // notified when live drops to 0 and when the acceptor closed
  bool stopping = false, acceptorClosed = false;
  std::vector<std::weak_ptr<HttpSession>> sessions;
  std::vector<std::weak_ptr<WsSession>> websockets;
  std::size_t live = 0;  // HTTP sessions and WebSockets
  std::size_t liveWs = 0;
  std::size_t connections = 0;                        // slots taken
  std::map<std::string, std::size_t> perAddress;  // slots taken per addressLimitKey
};

bool normalClose(const beast::error_code& ec) {
  return ec == asio::error::operation_aborted || ec == http::error::end_of_stream || ec == asio::error::eof ||
         ec == asio::error::connection_reset || ec == asio::error::broken_pipe;
}

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

// A WebSocket connection: reads messages into the hub, writes what the hub sends.
class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(beast::tcp_stream&& stream, std::shared_ptr<SharedState> state, std::string peer, std::shared_ptr<void> slot)
      : ws_(std::move(stream)), state_(std::move(state)), peer_(std::move(peer)), slot_(std::move(slot)) {}

  ~WsSession() {
    if (!joined_) return;
    if (client_) state_->options.hub->disconnect(client_);
    state_->log("ws: close " + peer_);
    state_->leaveWs();
  }

  void run(http::request<http::string_body> req) {
    if (!state_->joinWs(shared_from_this())) return;
    joined_ = true;
    const service::HubLimits& limits = state_->options.hub->limits();
    websocket::stream_base::timeout timeout{};
    timeout.handshake_timeout = std::chrono::seconds(30);
    timeout.idle_timeout = std::chrono::seconds(2 * std::max<long long>(1, limits.ping.count()));
    timeout.keep_alive_pings = true;
    beast::get_lowest_layer(ws_).expires_never();
    ws_.set_option(timeout);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "marzipan"); }));
    nextReadMax_ = limits.maxTextBytes;
    ws_.auto_fragment(false);
    ws_.async_accept(req, beast::bind_front_handler(&WsSession::onAccept, shared_from_this()));
  }

  // From any thread: queue a message (see the write conventions in http_server.hpp).
  void send(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
            bool latestWins) {
    asio::dispatch(ws_.get_executor(), [self = shared_from_this(), text = std::move(text), binary = std::move(binary),
                                        latestWins] { self->enqueue(text, binary, latestWins); });
  }
  // Messages handed over together (ClientLink::sendTogether): queued at once, in order, and
  // written corked so that they leave in one TCP push.
  void sendTogether(std::vector<service::ClientLink::Message> messages) {
    asio::dispatch(ws_.get_executor(), [self = shared_from_this(), messages = std::move(messages)]() mutable {
      for (std::size_t i = 0; i < messages.size(); ++i) {
        const Run run = messages.size() == 1 ? Run::alone : i + 1 < messages.size() ? Run::more : Run::last;
        self->enqueue(std::move(messages[i].text), std::move(messages[i].binary), false, run);
        if (self->closing_) return;
      }
    });
  }
  // Transient texts (ClientLink::sendTransient), handed over at once and written as one batch.
  void sendTransient(std::vector<service::ClientLink::Transient> texts) {
    asio::dispatch(ws_.get_executor(), [self = shared_from_this(), texts = std::move(texts)]() mutable {
      if (self->closing_) return;
      for (auto& t : texts) self->enqueueTransient(std::move(t.text), t.key);
      if (!self->writing_) self->doWrite();
    });
  }

  void close(websocket::close_code code, std::string reason) {
    asio::dispatch(ws_.get_executor(), [self = shared_from_this(), code, reason = std::move(reason)] {
      self->startClose(code, reason);
    });
  }

 private:
  // A message's place in a hand-over of several (sendTogether): the socket is corked from the
  // first and uncorked once the last is written.
  enum class Run : std::uint8_t { alone, more, last };
  struct Out {
    std::shared_ptr<const std::string> text;
    std::shared_ptr<const std::vector<std::uint8_t>> binary;
    bool latestWins = false;
    std::size_t charge = 0;  // what it counts against maxQueuedBytes (non-droppable only)
    bool transient = false;  // presence: replaced by its key, overtaken by everything else
    std::uint64_t key = 0;
    Run run = Run::alone;
    std::size_t size() const { return text ? text->size() : binary->size(); }
  };

  // The hub's view of this connection.
  class Link : public service::ClientLink {
   public:
    explicit Link(std::weak_ptr<WsSession> ws) : ws_(std::move(ws)) {}
    void sendText(std::string text) override {
      if (const auto ws = ws_.lock()) ws->send(std::make_shared<const std::string>(std::move(text)), nullptr, false);
    }
    void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>> frame, bool latestWins) override {
      if (const auto ws = ws_.lock()) ws->send(nullptr, std::move(frame), latestWins);
    }
    void sendTransient(std::vector<Transient> texts) override {
      if (const auto ws = ws_.lock()) ws->sendTransient(std::move(texts));
    }
    void sendTogether(std::vector<Message> messages) override {
      if (const auto ws = ws_.lock()) ws->sendTogether(std::move(messages));
    }
    void close(int code, std::string reason) override {
      if (const auto ws = ws_.lock()) ws->close(websocket::close_code(code), std::move(reason));
    }

   private:
    std::weak_ptr<WsSession> ws_;
  };

  void onAccept(beast::error_code ec) {
    if (ec) return fail(ec, "handshake");
    state_->log("ws: open " + peer_);
    client_ = state_->options.hub->connect(std::make_shared<Link>(weak_from_this()), peer_);
    doRead();
  }

  void doRead() {
    if (closing_) return;
    // Per message: nothing over max_text_bytes is buffered unless an editor announced an upload.
    ws_.read_message_max(nextReadMax_);
    ws_.async_read(buffer_, beast::bind_front_handler(&WsSession::onRead, shared_from_this()));
  }

  void onRead(beast::error_code ec, std::size_t bytes) {
    if (ec) return fail(ec, "read");
    const service::HubLimits& limits = state_->options.hub->limits();
    const auto data = buffer_.cdata();
    const auto* begin = static_cast<const std::uint8_t*>(data.data());
    nextReadMax_ = limits.maxTextBytes;
    if (ws_.got_text()) {
      if (bytes > limits.maxTextBytes)
        return startClose(websocket::close_code::too_big, "text message over max_text_bytes (" +
                                                              std::to_string(limits.maxTextBytes) + ")");
      std::string text(reinterpret_cast<const char*>(begin), bytes);
      if (const std::uint64_t upload = announcedUpload(text, limits)) nextReadMax_ = upload;
      state_->options.hub->text(client_, std::move(text));
    } else {
      const auto decoded = protocol::decodeFrameHeader({begin, bytes}, limits.maxBinaryBytes);
      if (!decoded) return startClose(websocket::close_code::policy_error, decoded.error->message.substr(0, 120));
      if (decoded.frame->header.kind != protocol::FrameKind::VolumeUpload)
        return startClose(websocket::close_code::policy_error, "clients send binary frames of kind 9 (volume upload) only");
      state_->options.hub->binary(client_, std::vector<std::uint8_t>(begin, begin + bytes));
    }
    buffer_.consume(buffer_.size());
    // A flat_buffer keeps its largest capacity for the connection's life: after an upload (even
    // a refused one) that would hold its size resident, up to max_binary_bytes per connection.
    if (buffer_.capacity() > limits.maxTextBytes) buffer_.shrink_to_fit();
    doRead();
  }

  // The size of the upload frame a volume.load in `text` announces when this client may upload
  // (Hub::mayUpload), else 0. The hub checks the request again; this only sizes the next read.
  // Parsed here on the I/O thread before any rate limit, so only a text the size of a real
  // volume.load (a few hundred bytes) is looked at: a bigger one reads no upload.
  std::uint64_t announcedUpload(const std::string& text, const service::HubLimits& limits) const {
    if (text.size() > kMaxVolumeLoadBytes || text.find("volume.load") == std::string::npos ||
        !state_->options.hub->mayUpload(client_))
      return 0;
    const protocol::ParsedRequest p = protocol::parseRequest(text);
    if (!p.request || p.request->method != protocol::Method::VolumeLoad) return 0;
    try {
      return protocol::parseVolumeLoadParams(p.request->params, limits.maxBinaryBytes - protocol::kFrameHeaderBytes).bytes +
             protocol::kFrameHeaderBytes;
    } catch (const std::exception&) {
      return 0;  // the hub answers the bad params
    }
  }

  void enqueue(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
               bool latestWins, Run run = Run::alone) {
    if (closing_) return;
    Out out{std::move(text), std::move(binary), latestWins};
    out.run = run;
    if (latestWins) {
      // Replace a pushed image still waiting (never the one being written).
      for (std::size_t i = writing_ ? 1 : 0; i < queue_.size(); ++i) {
        if (queue_[i].latestWins) {
          queue_[i] = std::move(out);
          return;
        }
      }
    } else {
      // The bound is for backlog, not for one message: an answer larger than half of it counts
      // as half, so a reader at full speed gets it and what follows; one that does not read
      // is closed by the next such answer.
      const std::size_t bound = state_->options.hub->limits().maxQueuedBytes;
      out.charge = std::min(out.size(), bound / 2);
      queuedBytes_ += out.charge;
      if (queuedBytes_ > bound) return startClose(websocket::close_code::policy_error, "too far behind");
    }
    // Waiting transient texts stay at the back: everything else goes ahead of them (a
    // hand-over's messages stay next to each other).
    auto at = queue_.end();
    while (at != queue_.begin() + (writing_ ? 1 : 0) && std::prev(at)->transient) --at;
    queue_.insert(at, std::move(out));
    // A hand-over is written once all of it is queued.
    if (!writing_ && run != Run::more) doWrite();
  }

  // Transient texts wait at the back of the queue, at most one per key (the newest) and at most
  // kMaxTransients in all (the oldest goes), so a congested client never has a backlog of them.
  // The caller starts the write.
  static constexpr std::size_t kMaxTransients = 64;
  void enqueueTransient(std::shared_ptr<const std::string> text, std::uint64_t key) {
    const std::size_t first = writing_ ? 1 : 0;
    std::size_t waiting = 0, oldest = queue_.size();
    for (std::size_t i = first; i < queue_.size(); ++i) {
      if (!queue_[i].transient) continue;
      if (queue_[i].key == key) {
        queue_[i].text = std::move(text);
        return;
      }
      if (waiting++ == 0) oldest = i;
    }
    if (waiting >= kMaxTransients) queue_.erase(queue_.begin() + std::ptrdiff_t(oldest));
    Out out{std::move(text), nullptr, false};
    out.transient = true;
    out.key = key;
    queue_.push_back(std::move(out));
  }

  // A batch of transient texts (a presence flush: one from each other client) leaves in one TCP
  // push instead of one per message: the socket is corked while a transient with more behind it
  // is written and uncorked when the queue runs dry. Anything else is written uncorked, so it
  // goes out at once with the transients before it and never waits for those after it.
  void cork(bool on) {
#ifdef TCP_CORK
    if (corked_ == on) return;
    corked_ = on;
    const int value = on ? 1 : 0;
    ::setsockopt(beast::get_lowest_layer(ws_).socket().native_handle(), IPPROTO_TCP, TCP_CORK, &value, sizeof value);
#else
    (void)on;
#endif
  }

  void doWrite() {
    writing_ = true;
    const Out& out = queue_.front();
    if (out.run == Run::more) cork(true);
    else if (out.run == Run::last) {
      // Corked by the hand-over's first message: onWrite uncorks once this one is written.
    } else if (!out.transient) {
      cork(false);
    } else if (queue_.size() > 1) {
      cork(true);
    }
    ws_.text(out.text != nullptr);
    if (out.text) {
      ws_.async_write(asio::buffer(*out.text), beast::bind_front_handler(&WsSession::onWrite, shared_from_this()));
    } else {
      ws_.async_write(asio::buffer(*out.binary), beast::bind_front_handler(&WsSession::onWrite, shared_from_this()));
    }
  }

  void onWrite(beast::error_code ec, std::size_t bytes) {
    state_->metrics.addBytesSent(bytes);
    writing_ = false;
    if (ec) return fail(ec, "write");
    queuedBytes_ -= queue_.front().charge;
    const bool endsRun = queue_.front().run == Run::last;
    queue_.pop_front();
    if (queue_.empty() || endsRun) cork(false);
    if (closeAfterWrite_) return doClose();
    if (!queue_.empty() && !closing_) doWrite();
  }

  void startClose(websocket::close_code code, std::string reason) {
    if (closing_) return;
    closing_ = true;
    closeReason_ = websocket::close_reason(code, beast::string_view(reason.data(), std::min<std::size_t>(reason.size(), 123)));
    closeReasonText_ = std::move(reason);
    if (client_) state_->options.hub->disconnect(client_);
    if (writing_) {
      closeAfterWrite_ = true;
      return;
    }
    doClose();
  }

  void doClose() {
    closeAfterWrite_ = false;
    cork(false);
    queue_.clear();
    state_->log("ws: closing " + peer_ + " with " + std::to_string(int(closeReason_.code)) + " " + closeReasonText_);
    ws_.async_close(closeReason_, [self = shared_from_this()](beast::error_code) {});
  }

  void fail(beast::error_code ec, std::string_view what) {
    closing_ = true;
    if (ec == websocket::error::closed || normalClose(ec)) return;
    state_->log("ws: " + peer_ + " " + std::string(what) + ": " + ec.message());
  }

  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
  std::shared_ptr<SharedState> state_;
  std::string peer_;
  std::shared_ptr<void> slot_;  // this connection's place under the connection bounds
  std::size_t nextReadMax_ = 0;  // the largest next message: max_text_bytes, or an announced upload
  std::shared_ptr<service::HubClient> client_;
  std::deque<Out> queue_;
  std::size_t queuedBytes_ = 0;  // the charges of what is queued, the one in flight included
  bool writing_ = false, closing_ = false, closeAfterWrite_ = false, joined_ = false;
  bool corked_ = false;  // TCP_CORK is set on the socket (see cork())
  websocket::close_reason closeReason_;
  std::string closeReasonText_;
};


class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, std::shared_ptr<SharedState> state, std::string peer, std::shared_ptr<void> slot)
      : stream_(std::move(socket)), state_(std::move(state)), peer_(std::move(peer)), slot_(std::move(slot)) {}

  ~HttpSession() {
    if (!joined_) return;
    state_->log("http: close " + peer_ + " after " + std::to_string(requests_) + " request(s)");
    state_->leave();
  }

  // Starts reading unless the server is stopping (then the connection is dropped).
  void run() {
    if (!state_->join(shared_from_this())) return;
    joined_ = true;
    state_->log("http: accept " + peer_);
    asio::dispatch(stream_.get_executor(), beast::bind_front_handler(&HttpSession::doRead, shared_from_this()));
  }

  // Posted by stop(): ends the session now unless a response is on its way.
  void closeIfIdle() {
    asio::dispatch(stream_.get_executor(), [self = shared_from_this()] {
      if (!self->busy_ && !self->upgraded_) self->stream_.cancel();
    });
  }

 private:
  void doRead() {
    busy_ = false;
    if (state_->isStopping()) return;  // stop() ran before this read could be cancelled
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(state_->options.maxHeaderBytes));
    parser_->body_limit(state_->options.maxBodyBytes);
    stream_.expires_after(state_->options.idleTimeout);
    http::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&HttpSession::onRead, shared_from_this()));
  }

  void onRead(beast::error_code ec, std::size_t) {
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

  void handle(http::request<http::string_body>&& req) {
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

  void sendFile(const StaticFile& file, bool head, bool keepAlive) {
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

  void sendText(http::status status, bool head, std::string text, bool keepAlive,
                std::string_view type = "text/plain; charset=utf-8") {
    if (static_cast<int>(status) >= 400) state_->metrics.countError(static_cast<int>(status));
    http::response<http::string_body> res{status, 11};
    decorate(res, type, keepAlive);
    if (status == http::status::method_not_allowed) res.set(http::field::allow, "GET, HEAD");
    res.content_length(text.size());
    if (!head) res.body() = std::move(text);
    send(std::move(res));
  }

  template <class Response>
  void decorate(Response& res, std::string_view type, bool keepAlive) {
    res.set(http::field::server, "marzipan");
    res.set(http::field::content_type, beast::string_view(type.data(), type.size()));
    res.set(http::field::cache_control, "no-cache");
    res.set("X-Content-Type-Options", "nosniff");
    res.keep_alive(keepAlive && !state_->isStopping());
  }

  // One write in flight: the next read starts only after this one completes.
  template <class Body>
  void send(http::response<Body>&& res) {
    auto message = std::make_shared<http::response<Body>>(std::move(res));
    const bool close = !message->keep_alive();
    stream_.expires_after(state_->options.idleTimeout);
    http::async_write(stream_, *message,
                      [self = shared_from_this(), message, close](beast::error_code ec, std::size_t bytes) {
                        self->onWrite(close, ec, bytes);
                      });
  }

  void onWrite(bool close, beast::error_code ec, std::size_t bytes) {
    state_->metrics.addBytesSent(bytes);
    if (ec) return fail(ec, "write");
    if (close || state_->isStopping()) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    doRead();
  }

  void fail(beast::error_code ec, std::string_view what) {
    if (normalClose(ec)) return;
    state_->log("http: " + peer_ + " " + std::string(what) + ": " + ec.message());
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<SharedState> state_;
  std::string peer_;
  std::shared_ptr<void> slot_;  // this connection's place under the connection bounds
  bool joined_ = false;  // counted in state_->live
  bool busy_ = false;  // a request has been read and its response not yet written
  bool upgraded_ = false;  // the socket went to a WsSession
  std::size_t requests_ = 0;
};

class Listener : public std::enable_shared_from_this<Listener> {
 public:
  Listener(asio::io_context& ioc, const tcp::endpoint& endpoint, std::shared_ptr<SharedState> state)
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

  std::uint16_t port() const { return port_; }

  void run() { doAccept(); }

  // Closes the acceptor on its strand; state_->acceptorClosed tells when it is done.
  void stop() {
    asio::post(acceptor_.get_executor(), [self = shared_from_this()] {
      self->close();
      const std::lock_guard lock(self->state_->mutex);
      self->state_->acceptorClosed = true;
      self->state_->idle.notify_all();
    });
  }

  // On the acceptor's strand, or once no I/O thread runs.
  void close() {
    beast::error_code ignored;
    acceptor_.close(ignored);
    retry_.cancel();
  }

 private:
  void doAccept() {
    acceptor_.async_accept(asio::make_strand(ioc_), beast::bind_front_handler(&Listener::onAccept, shared_from_this()));
  }

  void onAccept(beast::error_code ec, tcp::socket socket) {
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

  asio::io_context& ioc_;
  tcp::acceptor acceptor_;
  asio::steady_timer retry_{acceptor_.get_executor()};  // on the acceptor's strand
  std::shared_ptr<SharedState> state_;
  std::uint16_t port_ = 0;
};

}  // namespace

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
  std::vector<std::weak_ptr<HttpSession>> sessions;
  std::vector<std::weak_ptr<WsSession>> websockets;
  {
    const std::lock_guard lock(s.state->mutex);
    s.state->stopping = true;
    sessions = s.state->sessions;
    websockets = s.state->websockets;
  }
  s.listener->stop();
  // Running edits finish and answer before their clients are told to go.
  if (s.options.hub) s.options.hub->shutdown();
  for (const auto& weak : websockets) {
    if (const auto ws = weak.lock()) ws->close(websocket::close_code::going_away, "server shutting down");
  }
  if (s.signals) {
    asio::post(s.ioc, [&s] {
      beast::error_code ignored;
      s.signals->cancel(ignored);
    });
  }
  for (const auto& weak : sessions) {
    if (const auto session = weak.lock()) session->closeIfIdle();
  }
  {
    std::unique_lock lock(s.state->mutex);
    s.state->idle.wait_for(lock, s.options.shutdownGrace,
                           [&s] { return s.state->live == 0 && s.state->acceptorClosed; });
  }
  s.ioc.stop();
  for (std::thread& t : s.threads) t.join();
  s.threads.clear();
  s.listener->close();  // in case the grace ran out before the posted close ran
}

}  // namespace marzipan::net
