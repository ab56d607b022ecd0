// Binary frames: the fixed header in front of every binary WebSocket message (splat buffers,
// ray-cast images, meshes, volume files and uploads). protocol/PROTOCOL.md, section "Binary
// frames", is the contract; this is its C++ side.
//
// Conventions: every integer little-endian (marzipan::le); byte offsets from the frame start:
//    0  4  magic "MZPN"       4  2  u16 format version (1)   6  2  u16 kind (FrameKind)
//    8  4  u32 request id     12 8  u64 session revision     20 4  u32 payload length
//   24  ... payload, exactly `payload length` bytes, nothing after it.
// Decoding takes untrusted bytes: it never reads out of bounds, never throws and never
// allocates; every refusal is a FrameError whose code says which check failed.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace marzipan::protocol {

inline constexpr std::array<std::uint8_t, 4> kFrameMagic{'M', 'Z', 'P', 'N'};
inline constexpr std::uint16_t kFrameFormatVersion = 1;
inline constexpr std::size_t kFrameHeaderBytes = 24;
// The largest payload the header can describe; servers pass their own, smaller limit.
inline constexpr std::uint64_t kMaxFramePayload = 0xFFFFFFFFu;

enum class FrameKind : std::uint16_t {
  SplatsFull = 1,    // server -> client: every brick with points (engine/splats.hpp buffer)
  SplatsDelta = 2,   // server -> client: the listed bricks replace their old points
  FrameJpeg = 3,     // server -> client: a ray-cast image, JPEG file
  FramePng = 4,      // server -> client: a ray-cast image, PNG file
  MeshStl = 5,       // server -> client: binary STL
  MeshObj = 6,       // server -> client: Wavefront OBJ text
  MeshPly = 7,       // server -> client: binary little-endian PLY
  VolumeFile = 8,    // server -> client: a .mzv file (engine/volume_file.hpp)
  VolumeUpload = 9,  // client -> server: the file (.mzv or .vdb, as it says) for the volume.load it names
  MeshGlb = 10,      // server -> client: binary glTF 2.0 (.glb)
  VolumeVdb = 11,    // server -> client: an OpenVDB level set (.vdb), volume.save {format: "vdb"} (1.3)
};
inline constexpr std::uint16_t kMinFrameKind = 1, kMaxFrameKind = 11;

// True for the values of FrameKind.
constexpr bool isFrameKind(std::uint32_t value) { return value >= kMinFrameKind && value <= kMaxFrameKind; }
// "splats_full", "splats_delta", "frame_jpeg", ..., "volume_upload"; empty for other values.
std::string_view frameKindName(FrameKind kind);

struct FrameHeader {
  std::uint16_t version = kFrameFormatVersion;
  FrameKind kind = FrameKind::SplatsFull;
  std::uint32_t requestId = 0;  // the JSON-RPC id it answers; 0 for a push
  std::uint64_t revision = 0;   // the session revision the payload shows (0 in uploads)
  std::uint32_t payloadLength = 0;
  friend bool operator==(const FrameHeader&, const FrameHeader&) = default;
};

enum class FrameErrorCode {
  ShortHeader,     // fewer than 24 bytes
  BadMagic,        // bytes 0-3 are not "MZPN"
  BadVersion,      // format version other than 1
  BadKind,         // kind outside 1..11
  TooLarge,        // declared payload length above the caller's limit
  LengthMismatch,  // declared payload length differs from the bytes after the header
};
// "short_header", "bad_magic", "bad_version", "bad_kind", "too_large", "length_mismatch": the
// spelling used by the golden vectors (tests/protocol/vectors).
std::string_view frameErrorCodeName(FrameErrorCode code);

struct FrameError {
  FrameErrorCode code;
  std::string message;  // one sentence with the offending values, for a log line or a close reason
};

struct DecodedFrame {
  FrameHeader header;
  std::span<const std::uint8_t> payload;  // a view into the decoded bytes
};

// Either a frame or the reason it was refused.
struct FrameDecodeResult {
  std::optional<DecodedFrame> frame;
  std::optional<FrameError> error;
  explicit operator bool() const { return frame.has_value(); }
};

// The header and payload of one whole binary message. Checks, in this order: at least 24
// bytes, magic, version, kind, payload length <= maxPayload, payload length == bytes after
// the header. Never throws.
FrameDecodeResult decodeFrameHeader(std::span<const std::uint8_t> bytes, std::uint64_t maxPayload = kMaxFramePayload);

// The header followed by the payload. Throws std::invalid_argument for a kind outside
// FrameKind or a payload longer than kMaxFramePayload.
std::vector<std::uint8_t> encodeFrame(FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                                      std::span<const std::uint8_t> payload);
// The same frame made in place of `buffer`, whose first kFrameHeaderBytes are room the caller
// left for the header and the rest the payload: no copy of a payload written where it goes.
// Throws as encodeFrame, and std::invalid_argument for a buffer shorter than a header.
std::vector<std::uint8_t> encodeFrameInPlace(FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                                             std::vector<std::uint8_t> buffer);

}  // namespace marzipan::protocol
