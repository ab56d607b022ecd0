// Foot-point splats (METHOD.md section 5): the point cloud that shows the solid, produced per
// brick so that an edit re-extracts only the bricks around the ones it replaced.
//
// Conventions: sign and units as in volume.hpp (d < 0 inside, vu, voxel (i,j,k) at (i,j,k)).
// A voxel p of the domain is next to the surface when a 6-neighbour has the other sign
// (d < 0 versus d >= 0; outside the domain reads +band) or |d(p)| < kSurfaceNear. It yields
// exactly one splat: the unit normal n = g/|g|, g the central-difference gradient, and the
// foot point q = p - d(p) n, clamped to the brick's encodable range [o - 2, o + 10) per axis
// (o = 8 * brick); only fields that are not distances there (a solid cut by the domain's edge,
// bricks of -band next to bricks of +band) reach the clamp. Where g vanishes (a sheet thinner
// than a voxel) the splat stays at p with normal +z. Splats of a brick come in voxel order
// (x fastest, then y, then z), so extraction is deterministic and independent of threads.
//
// The splat of voxel p reads p's six neighbours, so a changed brick alters the splats of its
// six face neighbours too: bricksAroundChanges() lists what to re-extract after an edit.
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

#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

// |d| below which a voxel yields a splat even without a sign change among its neighbours: half
// the voxel diagonal, so every voxel whose cell the surface may cross is kept.
inline constexpr float kSurfaceNear = 0.87f;

inline constexpr std::uint16_t kSplatFormatVersion = 1;
inline constexpr std::size_t kSplatHeaderBytes = 16;
inline constexpr std::size_t kSplatBrickHeaderBytes = 8;
inline constexpr std::size_t kSplatPointBytes = 8;

struct Splat {
  float x, y, z;     // foot point, vu
  float nx, ny, nz;  // unit outward normal
  friend bool operator==(const Splat&, const Splat&) = default;
};

struct BrickSplats {
  Int3 brick;
  std::vector<Splat> points;  // at most one per voxel of the brick
  friend bool operator==(const BrickSplats&, const BrickSplats&) = default;
};

// The splats of one brick (any brick of brickDims(); throws EngineError OutOfDomain otherwise).
BrickSplats extractBrickSplats(const Volume& vol, Int3 brick);

// The splats of the given bricks, in the given order, empty bricks included (a delta). Every
// coordinate is checked before any work starts.
std::vector<BrickSplats> extractSplats(const Volume& vol, const std::vector<Int3>& bricks,
                                       ThreadPool& pool = ThreadPool::serial());

// Every brick that has splats, in z, y, x order (a full picture).
std::vector<BrickSplats> extractAllSplats(const Volume& vol, ThreadPool& pool = ThreadPool::serial());

// The bricks whose splats may differ after `changes`: each changed brick and its six face
// neighbours within vol.brickDims(), sorted z, y, x and without duplicates.
std::vector<Int3> bricksAroundChanges(const Volume& vol, const std::vector<BrickChange>& changes);

// The encoding documented above. Throws EngineError InvalidArgument for a brick listed twice,
// a coordinate outside [0, 65535] or more than 512 points in a brick.
std::vector<std::uint8_t> encodeSplats(const std::vector<BrickSplats>& bricks);
std::size_t encodedSplatsSize(const std::vector<BrickSplats>& bricks);

// Decodes any bytes without reading out of bounds: throws EngineError Format for a wrong magic,
// an unknown version, truncation, trailing bytes, a count the bytes cannot hold or a brick
// listed twice. Points come back at their quantized positions and normals.
std::vector<BrickSplats> decodeSplats(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
