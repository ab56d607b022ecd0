// The wire encoding of splats (PROTOCOL.md, splat buffers): a brick's foot points and normals,
// quantized to 8 bytes each, and in version 2 the colour and mask of painted bricks. The engine
// extracts the splats (server/engine/splats.hpp); this codec turns them into bytes and back, and
// is all a client needs to read them.
//
// Encoded buffer (all integers little-endian; byte offsets from the buffer start):
//
//   header, 16 bytes
//     0   4  magic: the bytes 'M' 'Z' 'S' 'P'
//     4   2  u16 version: 1 or 2
//     6   2  u16 reserved = 0
//     8   4  u32 B, number of brick blocks
//    12   4  u32 total number of points over all blocks
//   then B brick blocks, each
//     0   2  u16 brick x    (brick coordinates: voxel / 8)
//     2   2  u16 brick y
//     4   2  u16 brick z
//     6   2  u16 N: version 1, the number of points, 0..512 (0: "this brick has no points").
//            Version 2: bits 0..9 the number of points n (0..512), bit 15 set when the brick is
//            painted (then n >= 1), bits 10..14 zero.
//     8      n points. Unpainted (and every point of version 1), 8 bytes each: one u64
//            bits  0..13  X, bits 14..27  Y, bits 28..41  Z   (14-bit position codes)
//            bits 42..52  U, bits 53..63  V                   (11-bit octahedral normal)
//            Painted (version 2), 12 bytes each: the same u64, then u8 r, g, b, mask: the texel
//            of the voxel the foot point came from (sRGB colour bytes; mask 0 free .. 255 frozen).
//            The points of an unpainted brick take the session's base_color with mask 0.
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
//   Version 1 carries no colour: encoding bricks with texels as version 1 drops them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/cpp/values.hpp"  // Splat, BrickSplats, kSplatBrickSide, the position range

namespace marzipan {

// The newest version, which clients opt into (session.create/join `splats: 2`); version 1 is
// what a client that did not gets.
inline constexpr std::uint16_t kSplatFormatVersion = 2;
inline constexpr std::uint16_t kSplatFormatVersionPlain = 1;
inline constexpr std::size_t kSplatHeaderBytes = 16;
inline constexpr std::size_t kSplatBrickHeaderBytes = 8;
inline constexpr std::size_t kSplatPointBytes = 8;
inline constexpr std::size_t kSplatPaintedPointBytes = 12;  // version 2, painted bricks
inline constexpr std::uint32_t kSplatPaintedBit = 0x8000;   // version 2, in a block's N
inline constexpr std::uint32_t kSplatCountMask = 0x03ff;    // version 2, in a block's N

// One number per brick coordinate triple in [0, 65535]^3 (x | y << 21 | z << 42): how the codec
// finds a brick listed twice, and a key for keeping bricks by coordinates.
inline std::uint64_t splatBrickKey(Int3 b) {
  return std::uint64_t(std::uint32_t(b.x)) | std::uint64_t(std::uint32_t(b.y)) << 21 |
         std::uint64_t(std::uint32_t(b.z)) << 42;
}

// The encoding documented above, in `version` (1 or 2). Throws EngineError InvalidArgument for a
// brick listed twice, a coordinate outside [0, 65535], more than 512 points in a brick, texels
// that are neither none nor one per point, or an unknown version.
std::vector<std::uint8_t> encodeSplats(const std::vector<BrickSplats>& bricks,
                                       std::uint16_t version = kSplatFormatVersion);
std::size_t encodedSplatsSize(const std::vector<BrickSplats>& bricks, std::uint16_t version = kSplatFormatVersion);

// One brick's block as encodeSplats writes it, into `out` (resized to it; its buffer is reused):
// its 8-byte header, then its points. Checks the brick as encodeSplats does (coordinates, at
// most 512 points, finite values, texels). Two bricks whose blocks are equal read back the same
// on a client, whatever their floats were.
void encodeSplatBlock(const BrickSplats& brick, std::vector<std::uint8_t>& out,
                      std::uint16_t version = kSplatFormatVersion);
// The buffer of blocks made by encodeSplatBlock in `version`, in the given order: the same bytes
// as encodeSplats of their bricks (a server that keeps each brick's block, to send only those
// that changed, joins them without encoding again). Throws as encodeSplats does for a brick
// listed twice; a block that is not one brick's in that version (its length disagrees with its
// N) is an InvalidArgument. The buffer follows `headroom` bytes of room for the caller (a frame's
// header: encodeFrameInPlace), unset.
std::vector<std::uint8_t> joinSplatBlocks(const std::vector<std::span<const std::uint8_t>>& blocks,
                                          std::uint16_t version = kSplatFormatVersion, std::size_t headroom = 0);

// A valid buffer of either version as version 1 (the same bytes for version 1; version 2's
// colours dropped): what a client that did not opt into colour gets. Throws as decodeSplats.
std::vector<std::uint8_t> splatsAsVersion1(std::span<const std::uint8_t> bytes);

// Decodes any bytes without reading out of bounds: throws EngineError Format for a wrong magic,
// an unknown version, truncation, trailing bytes, a count the bytes cannot hold, a block's N
// with bits 10..14 set or painted without points (version 2), or a brick listed twice. Points
// come back at their quantized positions and normals, painted bricks with their texels. The
// buffer's version goes to *version when asked for.
std::vector<BrickSplats> decodeSplats(std::span<const std::uint8_t> bytes, std::uint16_t* version = nullptr);

}  // namespace marzipan
