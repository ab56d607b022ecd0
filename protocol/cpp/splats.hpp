// The wire encoding of splats (PROTOCOL.md, splat buffers): a brick's foot points and normals,
// quantized to 8 bytes each. The engine extracts the splats (server/engine/splats.hpp); this
// codec turns them into bytes and back, and is all a client needs to read them.
//
// Encoded buffer (all integers little-endian; byte offsets from the buffer start):
//
//   header, 16 bytes
//     0   4  magic: the bytes 'M' 'Z' 'S' 'P'
//     4   2  u16 version = 1
//     6   2  u16 reserved = 0
//     8   4  u32 B, number of brick blocks
//    12   4  u32 total number of points over all blocks
//   then B brick blocks, each
//     0   2  u16 brick x    (brick coordinates: voxel / 8)
//     2   2  u16 brick y
//     4   2  u16 brick z
//     6   2  u16 N, points in this brick, 0..512; N = 0 means "this brick has no points"
//     8  8N  N points, one u64 each:
//            bits  0..13  X, bits 14..27  Y, bits 28..41  Z   (14-bit position codes)
//            bits 42..52  U, bits 53..63  V                   (11-bit octahedral normal)
//   nothing after the last block.
//
//   Position, per axis: q = 8 * brick + C * 12 / 16384 - 2 for the code C in [0, 16383], i.e.
//   [-2, 10) vu around the brick origin in steps of 3/4096 vu (error <= 3.7e-4 vu per axis).
//   The encoder takes C = round((q - 8 * brick + 2) * 16384 / 12) clamped to [0, 16383].
//   Normal: u = (2U - 2047) / 2047, v = (2V - 2047) / 2047, z = 1 - |u| - |v|; where z < 0,
//   (u, v) <- ((1 - |v|) sign(u), (1 - |u|) sign(v)) with sign(0) = +1; n = (u, v, z) normalized
//   (error about 0.12 degrees at most). The encoder projects n onto the octahedron
//   |x| + |y| + |z| = 1, folds the lower half (z < 0) the same way, and rounds (x + 1) * 2047 / 2
//   and (y + 1) * 2047 / 2 (clamped to [0, 2047]).
//   A read with JavaScript's DataView: lo = getUint32(o, true), hi = getUint32(o + 4, true);
//   X = lo & 0x3fff, Y = (lo >>> 14) & 0x3fff, Z = (lo >>> 28) | ((hi & 0x3ff) << 4),
//   U = (hi >>> 10) & 0x7ff, V = hi >>> 21.
//
//   Bricks appear at most once per buffer. A buffer of every brick with points is a full
//   picture; a buffer of some bricks is a delta: each listed brick's points replace its old ones.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/cpp/values.hpp"  // Splat, BrickSplats, kSplatBrickSide, the position range

namespace marzipan {

inline constexpr std::uint16_t kSplatFormatVersion = 1;
inline constexpr std::size_t kSplatHeaderBytes = 16;
inline constexpr std::size_t kSplatBrickHeaderBytes = 8;
inline constexpr std::size_t kSplatPointBytes = 8;

// One number per brick coordinate triple in [0, 65535]^3 (x | y << 21 | z << 42): how the codec
// finds a brick listed twice, and a key for keeping bricks by coordinates.
inline std::uint64_t splatBrickKey(Int3 b) {
  return std::uint64_t(std::uint32_t(b.x)) | std::uint64_t(std::uint32_t(b.y)) << 21 |
         std::uint64_t(std::uint32_t(b.z)) << 42;
}

// The encoding documented above. Throws EngineError InvalidArgument for a brick listed twice,
// a coordinate outside [0, 65535] or more than 512 points in a brick.
std::vector<std::uint8_t> encodeSplats(const std::vector<BrickSplats>& bricks);
std::size_t encodedSplatsSize(const std::vector<BrickSplats>& bricks);

// One brick's block as encodeSplats writes it, into `out` (resized to it; its buffer is reused):
// its 8-byte header, then its points. Checks the brick as encodeSplats does (coordinates, at
// most 512 points, finite values). Two bricks whose blocks are equal read back the same on a
// client, whatever their floats were.
void encodeSplatBlock(const BrickSplats& brick, std::vector<std::uint8_t>& out);
// The buffer of blocks made by encodeSplatBlock, in the given order: the same bytes as
// encodeSplats of their bricks (a server that keeps each brick's block, to send only those that
// changed, joins them without encoding again). Throws as encodeSplats does for a brick listed
// twice; a block that is not one brick's (its length disagrees with its N) is an
// InvalidArgument.
std::vector<std::uint8_t> joinSplatBlocks(const std::vector<std::span<const std::uint8_t>>& blocks);

// Decodes any bytes without reading out of bounds: throws EngineError Format for a wrong magic,
// an unknown version, truncation, trailing bytes, a count the bytes cannot hold or a brick
// listed twice. Points come back at their quantized positions and normals.
std::vector<BrickSplats> decodeSplats(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
