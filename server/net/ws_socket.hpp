// The WebSocket stream's next layer (websocket::stream<WsSocket>): the TCP stream, on which
// Beast's own frames (the handshake's answer, pings, pongs, the close) and the data frames that
// WsSession writes itself take turns, each write whole before the next starts.
//
// Why WsSession writes its data frames itself: Beast writes one message per operation, so a
// change's response, notification and splat delta were three writes, three sendmsg calls and
// two setsockopt calls (TCP_CORK on and off) to leave in one TCP push; framed here (the same
// bytes as Beast's: RFC 6455, FIN set, unmasked, the shortest length form, no extensions) a
// hand-over is one gathered write and one sendmsg (docs/benchmark-log.md, capacity).
//
// Conventions: used on the connection's strand only, as Beast's stream is. A write that finds
// the socket taken waits for its turn in order. Beast writes a frame with one call of
// async_write_some, which here writes all of its bytes, so no write ever starts inside
// another's frame. Once Beast has written a close frame, writeFrames refuses (error::closed):
// nothing follows a close. The turn state is shared with the handlers of the writes in flight,
// so a write completing after the stream is gone touches nothing of it.
#pragma once

#include <boost/asio/async_result.hpp>
#include <boost/asio/buffer.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/buffers_range.hpp>
#include <boost/beast/core/role.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket/teardown.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <utility>

#include "net/beast.hpp"

namespace marzipan::net {

// A server's frame header for a whole message of `size` bytes (text or binary) into `out`;
// returns its length (2, 4 or 10 bytes).
inline std::size_t encodeWsFrameHeader(bool text, std::uint64_t size, std::array<std::uint8_t, 10>& out) {
  out[0] = std::uint8_t(0x80 | (text ? 0x1 : 0x2));
  if (size <= 125) {
    out[1] = std::uint8_t(size);
    return 2;
  }
  if (size <= 0xffff) {
    out[1] = 126;
    out[2] = std::uint8_t(size >> 8);
    out[3] = std::uint8_t(size);
    return 4;
  }
  out[1] = 127;
  for (int i = 0; i < 8; ++i) out[2 + i] = std::uint8_t(size >> (56 - 8 * i));
  return 10;
}

class WsSocket {
 public:
  using next_layer_type = beast::tcp_stream;
  using executor_type = next_layer_type::executor_type;

  explicit WsSocket(beast::tcp_stream&& stream) : next_(std::move(stream)) {}
  ~WsSocket() { turns_->gone = true; }
  WsSocket(const WsSocket&) = delete;
  WsSocket& operator=(const WsSocket&) = delete;

  executor_type get_executor() noexcept { return next_.get_executor(); }
  next_layer_type& next_layer() noexcept { return next_; }
  const next_layer_type& next_layer() const noexcept { return next_; }

  template <class Buffers, class Handler>
  auto async_read_some(const Buffers& buffers, Handler&& handler) {
    return next_.async_read_some(buffers, std::forward<Handler>(handler));
  }

  // Beast's frames: all of `buffers`, in turn.
  template <class Buffers, class Handler>
  auto async_write_some(const Buffers& buffers, Handler&& handler) {
    return asio::async_initiate<Handler, void(beast::error_code, std::size_t)>(
        [this](auto h, const Buffers& b) {
          for (const auto piece : beast::buffers_range_ref(b)) {
            // A close frame's first byte: FIN and opcode 8 (Beast writes each frame whole, from
            // its first byte; the handshake's answer begins with "HTTP").
            if (piece.size() > 0) turns_->closeSent |= *static_cast<const std::uint8_t*>(piece.data()) == 0x88;
            break;
          }
          inTurn([this, b, h = std::move(h)]() mutable { writeAll(b, std::move(h)); });
        },
        handler, buffers);
  }

  // WsSession's data frames, headers included, in turn; `done(ec, bytes)` once all are written
  // or failed. Refused with error::closed after a close frame.
  template <class Buffers, class Done>
  void writeFrames(Buffers buffers, Done done) {
    if (turns_->closeSent) {
      asio::post(next_.get_executor(), [done = std::move(done)]() mutable { done(websocket::error::closed, 0); });
      return;
    }
    inTurn([this, b = std::move(buffers), done = std::move(done)]() mutable {
      if (turns_->closeSent) {
        turns_->busy = false;
        startNext(turns_);
        return done(websocket::error::closed, 0);
      }
      writeAll(b, std::move(done));
    });
  }

 private:
  // A write waiting for its turn (move-only, as completion handlers are).
  struct Waiting {
    virtual ~Waiting() = default;
    virtual void start() = 0;
  };
  template <class F>
  struct WaitingFn final : Waiting {
    explicit WaitingFn(F&& f) : fn(std::move(f)) {}
    void start() override { fn(); }
    F fn;
  };
  struct Turns {
    bool busy = false;       // a write is on the socket
    bool closeSent = false;  // Beast wrote a close frame
    bool gone = false;       // the WsSocket is destroyed: waiting writes are dropped
    std::deque<std::unique_ptr<Waiting>> waiting;
  };

  template <class F>
  void inTurn(F&& start) {
    if (!turns_->busy) {
      turns_->busy = true;
      return start();
    }
    turns_->waiting.push_back(std::make_unique<WaitingFn<F>>(std::forward<F>(start)));
  }

  // The turn is over: the next waiting write starts (it holds the turn), unless none or gone.
  static void startNext(const std::shared_ptr<Turns>& turns) {
    if (turns->gone || turns->waiting.empty()) {
      turns->waiting.clear();
      return;
    }
    std::unique_ptr<Waiting> next = std::move(turns->waiting.front());
    turns->waiting.pop_front();
    turns->busy = true;
    next->start();
  }

  template <class Buffers, class Handler>
  void writeAll(const Buffers& buffers, Handler&& handler) {
    asio::async_write(next_, buffers,
                      [turns = turns_, h = std::forward<Handler>(handler)](beast::error_code ec, std::size_t n) mutable {
                        turns->busy = false;
                        startNext(turns);
                        h(ec, n);
                      });
  }

  beast::tcp_stream next_;
  std::shared_ptr<Turns> turns_ = std::make_shared<Turns>();
};

// Closing the WebSocket closes the TCP stream under it.
inline void teardown(beast::role_type role, WsSocket& s, beast::error_code& ec) {
  using beast::websocket::teardown;
  teardown(role, s.next_layer().socket(), ec);
}

template <class Handler>
void async_teardown(beast::role_type role, WsSocket& s, Handler&& handler) {
  using beast::websocket::async_teardown;
  async_teardown(role, s.next_layer().socket(), std::forward<Handler>(handler));
}

}  // namespace marzipan::net
