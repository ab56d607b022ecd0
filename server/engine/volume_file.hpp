// The native volume file (.mzv): a self-describing, checksummed snapshot of a Volume that
// stores only what the volume stores (bricks with data, and which uniform bricks are inside).
//
// Conventions: sign, units and brick layout as in volume.hpp. All integers and floats are
// little-endian (floats IEEE-754 binary32); byte offsets from the start of the file:
//
//   header, 48 bytes
//     0   4  magic: the bytes 'M' 'Z' 'V' 'F'
//     4   4  u32 format version = 1
//     8   4  u32 dims.x, in [8, 1024]
//    12   4  u32 dims.y, in [8, 1024]
//    16   4  u32 dims.z, in [8, 1024]
//    20   4  f32 band half-width, in [2, 8]
//    24   8  u64 revision
//    32   4  u32 brick side = 8 (files of another brick size are refused)
//    36   4  u32 P, number of stored bricks
//    40   4  u32 I, number of uniformly inside bricks
//    44   4  u32 reserved = 0
//   P stored bricks, 2056 bytes each, in z, y, x order of brick coordinates
//     0   2  u16 brick x   (brick coordinates: voxel / 8, each below ceil(dims / 8))
//     2   2  u16 brick y
//     4   2  u16 brick z
//     6   2  u16 reserved = 0
//     8 2048 512 f32 voxel values, index x + 8 * (y + 8 * z) (local coordinates)
//   I inside bricks, 8 bytes each, in z, y, x order
//     0   6  u16 x, y, z as above
//     6   2  u16 reserved = 0
//   version 2 only: the channels (channels.hpp)
//     0   4  base colour: u8 R, G, B (sRGB), u8 reserved = 0
//   version 2 only: C painted bricks (C: header bytes 44..48, which version 1 keeps 0), 2056
//   bytes each, in z, y, x order, each one of the stored bricks
//     0   8  u16 x, y, z, reserved = 0 as above
//     8 2048 512 texels, u8 R, G, B, mask each, index x + 8 * (y + 8 * z)
//   trailer, 4 bytes
//     0   4  u32 CRC-32 (IEEE 802.3, as zlib's crc32) of every byte before it
//
// Every brick not listed is uniformly outside (+band). The file size is exactly
// 48 + 2056 P + 8 I + 4 bytes (version 1) or 48 + 2056 P + 8 I + 4 + 2056 C + 4 (version 2).
// saveVolume writes version 1 for a volume with no channels and the clay base colour (the bytes
// it wrote before volumes had channels), version 2 otherwise; loadVolume reads both. A painted
// brick whose texels are all the base colour with weight 0 is refused (it is stored as none). Every value is finite and within [-band, band] (voxels of a
// brick past the domain's far edge included: Volume keeps them at +band); each section is in
// strictly increasing z, y, x order, no brick is both stored and inside, and no stored brick
// is uniform (its voxels in the domain all -band or all +band: it is listed as inside or left
// out, as Volume keeps it, so that equal fields give equal files and digests). Loading checks
// all of it and rebuilds the very bricks that were saved, so it preserves digest()
// (measures.hpp) and revision(); saving equal volumes gives equal files.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "volume.hpp"

namespace marzipan {

inline constexpr std::uint32_t kVolumeFileVersion = 2;  // the newest; version 1 still loads
inline constexpr std::size_t kVolumeFileHeaderBytes = 48;
inline constexpr std::size_t kVolumeFileBrickBytes = 8 + 4 * std::size_t(kBrickVoxels);
inline constexpr std::size_t kVolumeFileInsideBytes = 8;
inline constexpr std::size_t kVolumeFileTrailerBytes = 4;
inline constexpr std::size_t kVolumeFileBaseColorBytes = 4;
inline constexpr std::size_t kVolumeFilePaintBytes = 8 + 4 * std::size_t(kBrickVoxels);

std::vector<std::uint8_t> saveVolume(const Volume& vol);
// The size saveVolume(vol) will have, without building it.
std::size_t savedVolumeSize(const Volume& vol);

// Throws EngineError Format (field "file") for anything but a valid file as described above:
// wrong magic, unknown version, wrong size, checksum mismatch, out-of-range header values,
// bricks outside the grid, out of order or listed twice, uniform stored bricks, values NaN or
// beyond +-band, painted bricks that are not stored or hold only the base colour. Never reads out of bounds
// and allocates nothing from the header's counts before the file's size has confirmed them.
Volume loadVolume(std::span<const std::uint8_t> bytes);

// File helpers. Saving writes `path`.tmp and renames it over `path`, so a reader never sees a
// half-written file. I/O failures throw EngineError InvalidArgument (field "path").
void saveVolumeFile(const Volume& vol, const std::string& path);
Volume loadVolumeFile(const std::string& path);

// CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320, as zlib's crc32(0, data, size)).
std::uint32_t crc32Ieee(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
