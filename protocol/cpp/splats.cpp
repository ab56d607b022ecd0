// The splat wire codec. Byte layout and quantization: see splats.hpp.
#include "splats.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "protocol/cpp/errors.hpp"
#include "protocol/cpp/little_endian.hpp"

namespace marzipan {

namespace {

constexpr int kPosBits = kSplatPositionBits;
constexpr int kPosMax = kSplatPositionMax;
constexpr float kPosLow = kSplatPositionLow;
constexpr float kPosStep = kSplatPositionStep;
constexpr int kOctBits = 11;
constexpr int kOctMax = (1 << kOctBits) - 1;
constexpr int kMaxPointsPerBrick = kSplatBrickSide * kSplatBrickSide * kSplatBrickSide;

using namespace le;

constexpr std::uint8_t kMagic[4] = {'M', 'Z', 'S', 'P'};

float signOrPlus(float v) { return v < 0 ? -1.0f : 1.0f; }

std::uint32_t positionCode(float q, float origin) {
  const float t = std::clamp((q - origin - kPosLow) * (1 / kPosStep), 0.0f, float(kPosMax));
  return std::uint32_t(t + 0.5f);
}

std::uint64_t encodePoint(const Splat& s, Int3 origin) {
  float u = 0, v = 0;
  const float l1 = std::fabs(s.nx) + std::fabs(s.ny) + std::fabs(s.nz);
  if (l1 > 0) {
    const float inv = 1 / l1;
    u = s.nx * inv;
    v = s.ny * inv;
    if (s.nz < 0) {
      const float fu = (1 - std::fabs(v)) * signOrPlus(u), fv = (1 - std::fabs(u)) * signOrPlus(v);
      u = fu;
      v = fv;
    }
  }
  const auto oct = [](float c) {
    return std::uint64_t(std::clamp((c + 1) * (float(kOctMax) / 2), 0.0f, float(kOctMax)) + 0.5f);
  };
  return std::uint64_t(positionCode(s.x, float(origin.x))) |
         std::uint64_t(positionCode(s.y, float(origin.y))) << kPosBits |
         std::uint64_t(positionCode(s.z, float(origin.z))) << (2 * kPosBits) | oct(u) << (3 * kPosBits) |
         oct(v) << (3 * kPosBits + kOctBits);
}

Splat decodePoint(std::uint64_t w, Int3 origin) {
  Splat s;
  s.x = float(origin.x) + kPosLow + float(w & kPosMax) * kPosStep;
  s.y = float(origin.y) + kPosLow + float((w >> kPosBits) & kPosMax) * kPosStep;
  s.z = float(origin.z) + kPosLow + float((w >> (2 * kPosBits)) & kPosMax) * kPosStep;
  // (2U - 2047) / 2047 rather than 2U / 2047 - 1: the same value, but codes mirrored around
  // the middle give exactly opposite floats, so both codes of the folded seam decode alike.
  float u = float(2 * int((w >> (3 * kPosBits)) & kOctMax) - kOctMax) / float(kOctMax);
  float v = float(2 * int(w >> (3 * kPosBits + kOctBits)) - kOctMax) / float(kOctMax);
  const float z = 1 - std::fabs(u) - std::fabs(v);
  if (z < 0) {
    const float fu = (1 - std::fabs(v)) * signOrPlus(u), fv = (1 - std::fabs(u)) * signOrPlus(v);
    u = fu;
    v = fv;
  }
  const float inv = 1 / std::sqrt(u * u + v * v + z * z);
  s.nx = u * inv;
  s.ny = v * inv;
  s.nz = z * inv;
  return s;
}

[[noreturn]] void formatError(const std::string& message) { throw EngineError(ErrorKind::Format, "splats", message); }

void checkVersion(std::uint16_t version) {
  if (version != kSplatFormatVersionPlain && version != kSplatFormatVersion)
    throw EngineError(ErrorKind::InvalidArgument, "version", "splat buffers have versions 1 and 2");
}

// Whether the brick's block carries texels in `version`.
bool paintedIn(const BrickSplats& b, std::uint16_t version) {
  return version >= 2 && !b.texels.empty() && !b.points.empty();
}

std::size_t blockSize(const BrickSplats& b, std::uint16_t version) {
  return kSplatBrickHeaderBytes + (paintedIn(b, version) ? kSplatPaintedPointBytes : kSplatPointBytes) * b.points.size();
}

}  // namespace

std::size_t encodedSplatsSize(const std::vector<BrickSplats>& bricks, std::uint16_t version) {
  checkVersion(version);
  std::size_t n = kSplatHeaderBytes;
  for (const auto& b : bricks) n += blockSize(b, version);
  return n;
}

namespace {

// The checks of one brick (see encodeSplats).
void checkBrick(const BrickSplats& b) {
  for (int a = 0; a < 3; ++a)
    if (b.brick[a] < 0 || b.brick[a] > 0xffff)
      throw EngineError(ErrorKind::InvalidArgument, "brick", "coordinates must be in [0, 65535]");
  if (b.points.size() > std::size_t(kMaxPointsPerBrick))
    throw EngineError(ErrorKind::InvalidArgument, "points", "a brick holds at most 512 points");
  if (!b.texels.empty() && b.texels.size() != b.points.size())
    throw EngineError(ErrorKind::InvalidArgument, "texels", "a brick has no texels or one per point");
  for (const Splat& s : b.points)
    if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z) || !std::isfinite(s.nx) ||
        !std::isfinite(s.ny) || !std::isfinite(s.nz))
      throw EngineError(ErrorKind::InvalidArgument, "points", "positions and normals must be finite");
}

// Writes a checked brick's block at p; returns the byte after it.
std::uint8_t* writeBlock(const BrickSplats& b, std::uint8_t* p, std::uint16_t version) {
  const bool painted = paintedIn(b, version);
  put16(p, std::uint32_t(b.brick.x));
  put16(p + 2, std::uint32_t(b.brick.y));
  put16(p + 4, std::uint32_t(b.brick.z));
  put16(p + 6, std::uint32_t(b.points.size()) | (painted ? kSplatPaintedBit : 0));
  p += kSplatBrickHeaderBytes;
  const Int3 o{b.brick.x * kSplatBrickSide, b.brick.y * kSplatBrickSide, b.brick.z * kSplatBrickSide};
  for (std::size_t i = 0; i < b.points.size(); ++i) {
    put64(p, encodePoint(b.points[i], o));
    p += kSplatPointBytes;
    if (painted) {
      const SplatTexel& t = b.texels[i];
      p[0] = t.r, p[1] = t.g, p[2] = t.b, p[3] = t.mask;
      p += kSplatPaintedPointBytes - kSplatPointBytes;
    }
  }
  return p;
}

// A buffer of `bytes` bytes with its header written for blocks of the given brick keys holding
// `points` points in all; refuses a key listed twice.
std::vector<std::uint8_t> startBuffer(std::vector<std::uint64_t>& keys, std::size_t points, std::size_t bytes,
                                      std::uint16_t version) {
  std::sort(keys.begin(), keys.end());
  if (std::adjacent_find(keys.begin(), keys.end()) != keys.end())
    throw EngineError(ErrorKind::InvalidArgument, "brick", "a brick is listed twice");
  if (keys.size() > 0xffffffffu || points > 0xffffffffu)
    throw EngineError(ErrorKind::TooLarge, "splats", "more than 2^32 - 1 bricks or points");
  std::vector<std::uint8_t> out(bytes);
  std::uint8_t* p = out.data();
  std::memcpy(p, kMagic, 4);
  put16(p + 4, version);
  put16(p + 6, 0);
  put32(p + 8, std::uint32_t(keys.size()));
  put32(p + 12, std::uint32_t(points));
  return out;
}

// A block's header word N read in `version`: its point count and whether it is painted, or
// nothing when N is not one this version writes.
struct BlockCount {
  std::uint32_t n;
  bool painted;
  bool valid;
};
BlockCount readCount(std::uint32_t word, std::uint16_t version) {
  if (version == kSplatFormatVersionPlain) return {word, false, word <= std::uint32_t(kMaxPointsPerBrick)};
  const std::uint32_t n = word & kSplatCountMask;
  const bool painted = (word & kSplatPaintedBit) != 0;
  const bool valid = (word & ~(kSplatCountMask | kSplatPaintedBit)) == 0 &&
                     n <= std::uint32_t(kMaxPointsPerBrick) && (!painted || n > 0);
  return {n, painted, valid};
}

std::uint16_t readVersion(std::span<const std::uint8_t> bytes) {
  const std::size_t size = bytes.size();
  const std::uint8_t* p = bytes.data();
  if (size < kSplatHeaderBytes) formatError("truncated: " + std::to_string(size) + " bytes, the header alone takes 16");
  if (std::memcmp(p, kMagic, 4) != 0) formatError("not a splat buffer (wrong magic bytes)");
  const std::uint32_t version = get16(p + 4);
  if (version != kSplatFormatVersionPlain && version != kSplatFormatVersion)
    formatError("unsupported version " + std::to_string(version) + " (this build reads versions 1 and 2)");
  return std::uint16_t(version);
}

}  // namespace

std::vector<std::uint8_t> encodeSplats(const std::vector<BrickSplats>& bricks, std::uint16_t version) {
  checkVersion(version);
  std::vector<std::uint64_t> keys;
  keys.reserve(bricks.size());
  std::size_t points = 0;
  for (const auto& b : bricks) {
    checkBrick(b);
    keys.push_back(splatBrickKey(b.brick));
    points += b.points.size();
  }
  std::vector<std::uint8_t> out = startBuffer(keys, points, encodedSplatsSize(bricks, version), version);
  std::uint8_t* p = out.data() + kSplatHeaderBytes;
  for (const auto& b : bricks) p = writeBlock(b, p, version);
  return out;
}

void encodeSplatBlock(const BrickSplats& brick, std::vector<std::uint8_t>& out, std::uint16_t version) {
  checkVersion(version);
  checkBrick(brick);
  out.resize(blockSize(brick, version));
  writeBlock(brick, out.data(), version);
}

std::vector<std::uint8_t> joinSplatBlocks(const std::vector<std::span<const std::uint8_t>>& blocks,
                                          std::uint16_t version) {
  checkVersion(version);
  std::vector<std::uint64_t> keys;
  keys.reserve(blocks.size());
  std::size_t points = 0, bytes = kSplatHeaderBytes;
  for (const auto& b : blocks) {
    const BlockCount c = b.size() < kSplatBrickHeaderBytes ? BlockCount{0, false, false} : readCount(get16(b.data() + 6), version);
    if (!c.valid ||
        b.size() != kSplatBrickHeaderBytes + (c.painted ? kSplatPaintedPointBytes : kSplatPointBytes) * c.n)
      throw EngineError(ErrorKind::InvalidArgument, "blocks", "a block is not one brick's header and points");
    keys.push_back(splatBrickKey({int(get16(b.data())), int(get16(b.data() + 2)), int(get16(b.data() + 4))}));
    points += c.n;
    bytes += b.size();
  }
  std::vector<std::uint8_t> out = startBuffer(keys, points, bytes, version);
  std::uint8_t* p = out.data() + kSplatHeaderBytes;
  for (const auto& b : blocks) {
    if (!b.empty()) std::memcpy(p, b.data(), b.size());
    p += b.size();
  }
  return out;
}

std::vector<std::uint8_t> splatsAsVersion1(std::span<const std::uint8_t> bytes) {
  std::uint16_t version = 0;
  std::vector<BrickSplats> bricks = decodeSplats(bytes, &version);
  if (version == kSplatFormatVersionPlain) return {bytes.begin(), bytes.end()};
  // Decoded points are quantized already: they encode to the very codes they came from.
  return encodeSplats(bricks, kSplatFormatVersionPlain);
}

std::vector<BrickSplats> decodeSplats(std::span<const std::uint8_t> bytes, std::uint16_t* versionOut) {
  const std::uint16_t version = readVersion(bytes);
  const std::size_t size = bytes.size();
  const std::uint8_t* p = bytes.data();
  if (get16(p + 6) != 0) formatError("reserved header bytes must be 0");
  const std::uint32_t brickCount = get32(p + 8), pointCount = get32(p + 12);
  const std::size_t room = (size - kSplatHeaderBytes) / kSplatBrickHeaderBytes;
  if (brickCount > room || pointCount > room)
    formatError("counts (" + std::to_string(brickCount) + " bricks, " + std::to_string(pointCount) +
                " points) exceed what " + std::to_string(size) + " bytes can hold");

  std::vector<BrickSplats> out;
  out.reserve(brickCount);
  std::vector<std::uint64_t> keys;
  keys.reserve(brickCount);
  std::size_t at = kSplatHeaderBytes, points = 0;
  for (std::uint32_t i = 0; i < brickCount; ++i) {
    if (size - at < kSplatBrickHeaderBytes) formatError("truncated in the header of brick block " + std::to_string(i));
    const Int3 b{int(get16(p + at)), int(get16(p + at + 2)), int(get16(p + at + 4))};
    const std::uint32_t word = get16(p + at + 6);
    const BlockCount c = readCount(word, version);
    at += kSplatBrickHeaderBytes;
    if (!c.valid)
      formatError("brick block " + std::to_string(i) + " has N = " + std::to_string(word) +
                  (version == kSplatFormatVersionPlain
                       ? " (at most 512 points)"
                       : " (version 2: at most 512 points in bits 0..9, bits 10..14 zero, painted only with points)"));
    const std::size_t pointBytes = c.painted ? kSplatPaintedPointBytes : kSplatPointBytes;
    if ((size - at) / pointBytes < c.n) formatError("truncated in the points of brick block " + std::to_string(i));
    BrickSplats bs{b, {}, {}};
    bs.points.reserve(c.n);
    if (c.painted) bs.texels.reserve(c.n);
    const Int3 o{b.x * kSplatBrickSide, b.y * kSplatBrickSide, b.z * kSplatBrickSide};
    for (std::uint32_t k = 0; k < c.n; ++k, at += pointBytes) {
      bs.points.push_back(decodePoint(get64(p + at), o));
      if (c.painted) bs.texels.push_back({p[at + 8], p[at + 9], p[at + 10], p[at + 11]});
    }
    points += c.n;
    keys.push_back(splatBrickKey(b));
    out.push_back(std::move(bs));
  }
  if (at != size) formatError(std::to_string(size - at) + " trailing bytes after the last brick block");
  if (points != pointCount)
    formatError("the header announces " + std::to_string(pointCount) + " points, the blocks hold " +
                std::to_string(points));
  std::sort(keys.begin(), keys.end());
  if (std::adjacent_find(keys.begin(), keys.end()) != keys.end()) formatError("a brick is listed twice");
  if (versionOut) *versionOut = version;
  return out;
}

}  // namespace marzipan
