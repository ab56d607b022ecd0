// WsSession (see websocket_session.hpp): the read loop into the hub and the outgoing queue.
#include "net/websocket_session.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/beast/core/bind_handler.hpp>
#include <boost/beast/core/stream_traits.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <chrono>
#include <exception>
#include <iterator>
#include <utility>

#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/rpc.hpp"

namespace marzipan::net {

namespace {

// The largest text read for the upload it announces: a volume.load
// ({"jsonrpc","id","method","params":{"bytes","format"}}) is under 200 bytes as clients write it.
constexpr std::size_t kMaxVolumeLoadBytes = 4 * 1024;

// Transient texts wait at the back of the queue, at most one per key (the newest) and at most
// kMaxTransients in all (the oldest goes), so a congested client never has a backlog of them.
constexpr std::size_t kMaxTransients = 64;

// The most messages one gathered write takes: two buffers each (header, payload), within the 64
// that one sendmsg of Asio's takes.
constexpr std::size_t kMaxBatch = 32;

}  // namespace

class WsSession::Link : public service::ClientLink {
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
  void sendAll(std::vector<Item> items) override {
    if (const auto ws = ws_.lock()) ws->sendAll(std::move(items));
  }
  void close(int code, std::string reason) override {
    if (const auto ws = ws_.lock()) ws->close(websocket::close_code(code), std::move(reason));
  }
  Carrier* carrier() override;
  std::shared_ptr<WsSession> session() const { return ws_.lock(); }

 private:
  std::weak_ptr<WsSession> ws_;
};

// What one piece of the hub's work sent several connections, in one post to the network thread:
// onto the first live connection's strand, where each connection is handed its items (its own
// at once, the others' posted onto their strands from the network thread, which wakes no one).
// Each connection's items take its ticket here, so they keep their place among what else it is
// handed (the Order convention of websocket_session.hpp).
class WsSession::Carrier final : public service::ClientLink::Carrier {
 public:
  void carry(std::vector<service::ClientLink::Delivery> deliveries) override {
    struct Handed {
      std::shared_ptr<WsSession> ws;
      std::uint64_t ticket;
      std::vector<service::ClientLink::Item> items;
    };
    std::vector<Handed> live;
    live.reserve(deliveries.size());
    for (auto& d : deliveries)
      if (auto ws = static_cast<const Link&>(*d.link).session()) {
        const std::uint64_t ticket = ws->takeTicket();
        live.push_back({std::move(ws), ticket, std::move(d.items)});
      }
    if (live.empty()) return;
    const auto executor = live.front().ws->ws_.get_executor();
    asio::post(executor, [live = std::move(live)]() mutable {
      for (Handed& h : live) h.ws->deliver(h.ticket, std::move(h.items));
    });
  }
};

// Every connection's link has the one carrier (it holds nothing of its own).
service::ClientLink::Carrier* WsSession::Link::carrier() {
  static WsSession::Carrier shared;
  return &shared;
}

WsSession::WsSession(beast::tcp_stream&& stream, std::shared_ptr<SharedState> state, std::string peer,
                     std::shared_ptr<void> slot)
    : ws_(std::move(stream)), state_(std::move(state)), peer_(std::move(peer)), slot_(std::move(slot)) {}

WsSession::~WsSession() {
  if (!joined_) return;
  if (client_) state_->options.hub->disconnect(client_);
  state_->log("ws: close " + peer_);
  state_->leaveWs();
}

void WsSession::run(http::request<http::string_body> req) {
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

// In turn, `apply` runs at once (no copy of it is made); early, it waits in early_, which holds
// no reference to the session: it runs from a later hand-over of the same session, or never.
// The turn moves on before a hand-over is applied, so one that throws (out of memory) does not
// hold back those after it.
template <class Apply>
void WsSession::inTurn(std::uint64_t ticket, Apply&& apply) {
  if (ticket == turn_) {
    ++turn_;
    apply();
  } else {
    early_.emplace(ticket, std::forward<Apply>(apply));
  }
  if (!early_.empty()) runEarly();
}

void WsSession::runEarly() {
  while (!early_.empty() && early_.begin()->first == turn_) {
    const std::function<void()> waiting = std::move(early_.begin()->second);
    early_.erase(early_.begin());
    ++turn_;
    waiting();
  }
}

void WsSession::send(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
                     bool latestWins) {
  asio::dispatch(ws_.get_executor(), [self = shared_from_this(), ticket = takeTicket(), text = std::move(text),
                                      binary = std::move(binary), latestWins] {
    self->inTurn(ticket, [s = self.get(), text, binary, latestWins] {
      s->enqueue(text, binary, latestWins);
      s->write();
    });
  });
}

void WsSession::sendTogether(std::vector<service::ClientLink::Message> messages) {
  asio::dispatch(ws_.get_executor(), [self = shared_from_this(), ticket = takeTicket(), messages = std::move(messages)]() mutable {
    self->inTurn(ticket, [s = self.get(), messages = std::move(messages)]() mutable {
      for (auto& m : messages) s->enqueue(std::move(m.text), std::move(m.binary), false);
      s->write();
    });
  });
}

void WsSession::sendTransient(std::vector<service::ClientLink::Transient> texts) {
  asio::dispatch(ws_.get_executor(), [self = shared_from_this(), ticket = takeTicket(), texts = std::move(texts)]() mutable {
    self->inTurn(ticket, [s = self.get(), texts = std::move(texts)]() mutable {
      if (s->closing_) return;
      for (auto& t : texts) s->enqueueTransient(std::move(t.text), t.key);
      s->write();
    });
  });
}

void WsSession::sendAll(std::vector<service::ClientLink::Item> items) { deliver(takeTicket(), std::move(items)); }

void WsSession::deliver(std::uint64_t ticket, std::vector<service::ClientLink::Item> items) {
  asio::dispatch(ws_.get_executor(), [self = shared_from_this(), ticket, items = std::move(items)]() mutable {
    self->inTurn(ticket, [s = self.get(), items = std::move(items)]() mutable {
      for (auto& i : items) {
        if (s->closing_) return;
        if (i.transient) s->enqueueTransient(std::move(i.text), i.key);
        else s->enqueue(std::move(i.text), std::move(i.binary), i.latestWins);
      }
      s->write();
    });
  });
}

void WsSession::close(websocket::close_code code, std::string reason) {
  asio::dispatch(ws_.get_executor(), [self = shared_from_this(), ticket = takeTicket(), code, reason = std::move(reason)] {
    self->inTurn(ticket, [s = self.get(), code, reason] { s->startClose(code, reason); });
  });
}

void WsSession::onAccept(beast::error_code ec) {
  if (ec) return fail(ec, "handshake");
  state_->log("ws: open " + peer_);
  client_ = state_->options.hub->connect(std::make_shared<Link>(weak_from_this()), peer_);
  doRead();
}

void WsSession::doRead() {
  if (closing_) return;
  // Per message: nothing over max_text_bytes is buffered unless an editor announced an upload.
  ws_.read_message_max(nextReadMax_);
  ws_.async_read(buffer_, beast::bind_front_handler(&WsSession::onRead, shared_from_this()));
}

void WsSession::onRead(beast::error_code ec, std::size_t bytes) {
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
std::uint64_t WsSession::announcedUpload(const std::string& text, const service::HubLimits& limits) const {
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

void WsSession::enqueue(std::shared_ptr<const std::string> text, std::shared_ptr<const std::vector<std::uint8_t>> binary,
                        bool latestWins) {
  if (closing_) return;
  Out out{std::move(text), std::move(binary), latestWins};
  if (latestWins) {
    // Replace a pushed image still waiting (never one being written).
    for (std::size_t i = 0; i < queue_.size(); ++i) {
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
  while (at != queue_.begin() && std::prev(at)->transient) --at;
  queue_.insert(at, std::move(out));
}

// Replaces a waiting transient of the same key, else appends (see kMaxTransients). The caller
// starts the write.
void WsSession::enqueueTransient(std::shared_ptr<const std::string> text, std::uint64_t key) {
  std::size_t waiting = 0, oldest = queue_.size();
  for (std::size_t i = 0; i < queue_.size(); ++i) {
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

void WsSession::write() {
  if (writing_.empty() && !closing_ && !queue_.empty()) doWrite();
}

// Everything waiting (up to kMaxBatch messages) in one gathered write: one sendmsg, one TCP push
// for a hand-over or a batch of transients, where a write per message needed the socket corked.
void WsSession::doWrite() {
  const std::size_t n = std::min(queue_.size(), kMaxBatch);
  writing_.clear();
  writing_.reserve(n);
  for (std::size_t i = 0; i < n; ++i) writing_.push_back(std::move(queue_[i]));
  queue_.erase(queue_.begin(), queue_.begin() + std::ptrdiff_t(n));
  std::vector<asio::const_buffer> buffers;
  buffers.reserve(2 * n);
  for (Out& out : writing_) {
    const std::size_t headerBytes = encodeWsFrameHeader(out.text != nullptr, out.size(), out.header);
    buffers.emplace_back(out.header.data(), headerBytes);
    if (out.text) buffers.emplace_back(asio::buffer(*out.text));
    else buffers.emplace_back(asio::buffer(*out.binary));
  }
  ws_.next_layer().writeFrames(std::move(buffers), beast::bind_front_handler(&WsSession::onWrite, shared_from_this()));
}

void WsSession::onWrite(beast::error_code ec, std::size_t) {
  std::size_t payload = 0, charges = 0;
  for (const Out& out : writing_) {
    payload += out.size();
    charges += out.charge;
  }
  writing_.clear();
  if (ec) return fail(ec, "write");
  state_->metrics.addBytesSent(payload);  // message bytes, as Beast counted them
  queuedBytes_ -= charges;
  if (closeAfterWrite_) return doClose();
  if (!closing_) write();
}

void WsSession::startClose(websocket::close_code code, std::string reason) {
  if (closing_) return;
  closing_ = true;
  closeReason_ = websocket::close_reason(code, beast::string_view(reason.data(), std::min<std::size_t>(reason.size(), 123)));
  closeReasonText_ = std::move(reason);
  if (client_) state_->options.hub->disconnect(client_);
  if (!writing_.empty()) {
    closeAfterWrite_ = true;
    return;
  }
  doClose();
}

void WsSession::doClose() {
  closeAfterWrite_ = false;
  queue_.clear();
  state_->log("ws: closing " + peer_ + " with " + std::to_string(int(closeReason_.code)) + " " + closeReasonText_);
  ws_.async_close(closeReason_, [self = shared_from_this()](beast::error_code) {});
}

void WsSession::fail(beast::error_code ec, std::string_view what) {
  closing_ = true;
  if (ec == websocket::error::closed || normalClose(ec)) return;
  state_->log("ws: " + peer_ + " " + std::string(what) + ": " + ec.message());
}

}  // namespace marzipan::net
