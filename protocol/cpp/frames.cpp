// Encoding and checked decoding of binary frame headers (see frames.hpp). Messages quote the
// offending values so that a close reason or a log line explains itself.
#include "frames.hpp"

#include <algorithm>
#include <stdexcept>

#include "protocol/cpp/little_endian.hpp"

namespace marzipan::protocol {
namespace {

constexpr std::size_t kVersionOffset = 4, kKindOffset = 6, kRequestIdOffset = 8, kRevisionOffset = 12,
                      kLengthOffset = 20;

std::string hexByte(std::uint8_t b) {
  constexpr char kDigits[] = "0123456789abcdef";
  return std::string{kDigits[b >> 4], kDigits[b & 15]};
}

FrameDecodeResult refuse(FrameErrorCode code, std::string message) {
  return FrameDecodeResult{std::nullopt, FrameError{code, std::move(message)}};
}

// What encodeFrame and encodeFrameInPlace refuse, checked before either allocates or writes.
void checkFrame(FrameKind kind, std::size_t payloadBytes) {
  if (!isFrameKind(std::uint32_t(kind)))
    throw std::invalid_argument("binary frame kind " + std::to_string(unsigned(kind)) + " is unknown");
  if (payloadBytes > kMaxFramePayload)
    throw std::invalid_argument("binary frame payload of " + std::to_string(payloadBytes) +
                                " bytes does not fit the 32-bit length field");
}

}  // namespace

std::string_view frameKindName(FrameKind kind) {
  switch (kind) {
    case FrameKind::SplatsFull: return "splats_full";
    case FrameKind::SplatsDelta: return "splats_delta";
    case FrameKind::FrameJpeg: return "frame_jpeg";
    case FrameKind::FramePng: return "frame_png";
    case FrameKind::MeshStl: return "mesh_stl";
    case FrameKind::MeshObj: return "mesh_obj";
    case FrameKind::MeshPly: return "mesh_ply";
    case FrameKind::VolumeFile: return "volume_file";
    case FrameKind::VolumeUpload: return "volume_upload";
    case FrameKind::MeshGlb: return "mesh_glb";
    case FrameKind::VolumeVdb: return "volume_vdb";
  }
  return {};
}

std::string_view frameErrorCodeName(FrameErrorCode code) {
  switch (code) {
    case FrameErrorCode::ShortHeader: return "short_header";
    case FrameErrorCode::BadMagic: return "bad_magic";
    case FrameErrorCode::BadVersion: return "bad_version";
    case FrameErrorCode::BadKind: return "bad_kind";
    case FrameErrorCode::TooLarge: return "too_large";
    case FrameErrorCode::LengthMismatch: return "length_mismatch";
  }
  return {};
}

FrameDecodeResult decodeFrameHeader(std::span<const std::uint8_t> bytes, std::uint64_t maxPayload) {
  if (bytes.size() < kFrameHeaderBytes)
    return refuse(FrameErrorCode::ShortHeader, "binary frame of " + std::to_string(bytes.size()) +
                                                   " bytes is shorter than its 24-byte header");
  if (!std::equal(kFrameMagic.begin(), kFrameMagic.end(), bytes.begin())) {
    std::string got;
    for (std::size_t i = 0; i < kFrameMagic.size(); ++i) got += hexByte(bytes[i]);
    return refuse(FrameErrorCode::BadMagic, "binary frame magic must be \"MZPN\" (4d5a504e), got " + got);
  }
  const std::uint8_t* p = bytes.data();
  FrameHeader h;
  h.version = std::uint16_t(le::get16(p + kVersionOffset));
  if (h.version != kFrameFormatVersion)
    return refuse(FrameErrorCode::BadVersion, "binary frame format version " + std::to_string(h.version) +
                                                  " is not supported (supported: 1)");
  const std::uint32_t kind = le::get16(p + kKindOffset);
  if (!isFrameKind(kind))
    return refuse(FrameErrorCode::BadKind, "binary frame kind " + std::to_string(kind) + " is unknown (known: 1 to 11)");
  h.kind = FrameKind(kind);
  h.requestId = le::get32(p + kRequestIdOffset);
  h.revision = le::get64(p + kRevisionOffset);
  h.payloadLength = le::get32(p + kLengthOffset);
  if (h.payloadLength > maxPayload)
    return refuse(FrameErrorCode::TooLarge, "binary frame payload of " + std::to_string(h.payloadLength) +
                                                " bytes is over the limit of " + std::to_string(maxPayload));
  const std::size_t following = bytes.size() - kFrameHeaderBytes;
  if (h.payloadLength != following)
    return refuse(FrameErrorCode::LengthMismatch, "binary frame header declares " + std::to_string(h.payloadLength) +
                                                      " payload bytes but " + std::to_string(following) + " follow");
  return FrameDecodeResult{DecodedFrame{h, bytes.subspan(kFrameHeaderBytes)}, std::nullopt};
}

std::vector<std::uint8_t> encodeFrame(FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                                      std::span<const std::uint8_t> payload) {
  checkFrame(kind, payload.size());
  // The header's room left, the payload appended: no zeroing of what the copy fills.
  std::vector<std::uint8_t> out;
  out.reserve(kFrameHeaderBytes + payload.size());
  out.resize(kFrameHeaderBytes);
  out.insert(out.end(), payload.begin(), payload.end());
  return encodeFrameInPlace(kind, requestId, revision, std::move(out));
}

std::vector<std::uint8_t> encodeFrameInPlace(FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                                             std::vector<std::uint8_t> buffer) {
  if (buffer.size() < kFrameHeaderBytes)
    throw std::invalid_argument("a frame's buffer of " + std::to_string(buffer.size()) + " bytes has no room for its header");
  const std::size_t payload = buffer.size() - kFrameHeaderBytes;
  checkFrame(kind, payload);
  std::uint8_t* p = buffer.data();
  std::copy(kFrameMagic.begin(), kFrameMagic.end(), p);
  le::put16(p + kVersionOffset, kFrameFormatVersion);
  le::put16(p + kKindOffset, std::uint16_t(kind));
  le::put32(p + kRequestIdOffset, requestId);
  le::put64(p + kRevisionOffset, revision);
  le::put32(p + kLengthOffset, std::uint32_t(payload));
  return buffer;
}

}  // namespace marzipan::protocol
