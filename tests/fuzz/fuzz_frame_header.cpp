// Fuzz target: the binary frame header (protocol/cpp/frames.hpp, decodeFrameHeader), under the
// protocol's own limit and under small ones. A frame it accepts must re-encode to the very
// same bytes; a refusal must carry a named code and a short message.
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "fuzz.hpp"
#include "protocol/cpp/frames.hpp"

using namespace marzipan::protocol;
using marzipan::fuzz::expect;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto bytes = marzipan::fuzz::bytesOf(data, size);
  for (const std::uint64_t limit : {kMaxFramePayload, std::uint64_t(15), std::uint64_t(0)}) {
    const FrameDecodeResult r = decodeFrameHeader(bytes, limit);
    expect(r.frame.has_value() != r.error.has_value(), "a decode gives a frame or an error, not both");
    if (r.error) {
      expect(!frameErrorCodeName(r.error->code).empty(), "every error code has a name");
      marzipan::fuzz::expectMessage(r.error->message);
      continue;
    }
    const DecodedFrame& f = *r.frame;
    expect(isFrameKind(std::uint32_t(f.header.kind)) && !frameKindName(f.header.kind).empty(), "the kind is known");
    expect(f.header.payloadLength <= limit, "the payload is within the limit");
    expect(f.payload.size() == f.header.payloadLength, "the payload is as long as declared");
    expect(f.payload.data() == data + kFrameHeaderBytes, "the payload is the bytes after the header");
    const auto again = encodeFrame(f.header.kind, f.header.requestId, f.header.revision, f.payload);
    expect(std::equal(again.begin(), again.end(), bytes.begin(), bytes.end()), "an accepted frame re-encodes to itself");
  }
  return 0;
}
