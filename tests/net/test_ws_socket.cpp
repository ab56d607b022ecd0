// The frame headers WsSession writes for its data messages (net/ws_socket.hpp): RFC 6455's
// examples (section 5.7) and the length forms' edges, and the same bytes as Beast's own writer
// for a server's whole unmasked frame.
#include <catch2/catch.hpp>

#include <boost/beast/core/flat_static_buffer.hpp>
#include <boost/beast/websocket/detail/frame.hpp>

#include <array>
#include <cstdint>
#include <vector>

#include "net/ws_socket.hpp"

namespace {

std::vector<std::uint8_t> header(bool text, std::uint64_t size) {
  std::array<std::uint8_t, 10> out{};
  const std::size_t n = marzipan::net::encodeWsFrameHeader(text, size, out);
  return {out.begin(), out.begin() + std::ptrdiff_t(n)};
}

// Beast's frame header writer, as its write operations call it for a server's frame.
std::vector<std::uint8_t> beastHeader(bool text, std::uint64_t size) {
  namespace detail = boost::beast::websocket::detail;
  detail::frame_header fh;
  fh.op = text ? detail::opcode::text : detail::opcode::binary;
  fh.fin = true;
  fh.rsv1 = fh.rsv2 = fh.rsv3 = false;
  fh.len = size;
  fh.mask = false;
  detail::fh_buffer b;
  detail::write(b, fh);
  const auto* p = static_cast<const std::uint8_t*>(b.data().data());
  return {p, p + b.size()};
}

}  // namespace

TEST_CASE("ws frames: RFC 6455's examples of unmasked frames", "[net][ws]") {
  CHECK(header(true, 5) == std::vector<std::uint8_t>{0x81, 0x05});                    // "Hello"
  CHECK(header(false, 256) == std::vector<std::uint8_t>{0x82, 0x7E, 0x01, 0x00});    // 256 bytes
  CHECK(header(false, 65536) == std::vector<std::uint8_t>{0x82, 0x7F, 0, 0, 0, 0, 0, 0x01, 0x00, 0x00});  // 64 KiB
}

TEST_CASE("ws frames: each length form at its edges, as Beast writes it", "[net][ws]") {
  for (const std::uint64_t size : {0ull, 1ull, 125ull, 126ull, 127ull, 65535ull, 65536ull, 0x1234567890ull}) {
    INFO(size);
    CHECK(header(true, size) == beastHeader(true, size));
    CHECK(header(false, size) == beastHeader(false, size));
  }
  CHECK(header(false, 125).size() == 2);
  CHECK(header(false, 126).size() == 4);
  CHECK(header(false, 65535).size() == 4);
  CHECK(header(false, 65536).size() == 10);
}
