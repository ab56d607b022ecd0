// OpenVDB level-set files (.vdb) in and out; built only with -DMARZIPAN_WITH_OPENVDB=ON
// (Debian's libopenvdb-dev), which defines MARZIPAN_HAS_OPENVDB for code that uses it.
//
// Conventions: one FloatGrid named "surface", class level set, voxel size 1 (1 vu) and index
// (i, j, k) at the point (i, j, k), as in volume.hpp; background = the band half-width w;
// active voxels are those with |d| < w; inactive values carry the sign (-w inside, +w
// outside), as OpenVDB's level-set tools expect.
// - Colour: a volume that carries colour (marching_cubes.hpp, carriesColor) also gets a Vec3SGrid
//   named "color" after the level set, same transform: linear-light RGB in [0, 1] (the sRGB
//   bytes decoded, color_space.hpp, as VFX tools work in linear light), background the base
//   colour, active at every voxel of a painted brick whose colour is not the base colour. The
//   mask weight is not written. Reading a file that has such a grid gives every voxel of the
//   volume's stored bricks its colour there (encoded back to sRGB: a colour written here comes
//   back exactly), weight 0; a file without one gives a volume with no channels.
//
// The stream forms serve clients (volume.save / volume.load over the API) without temporary
// files; the path forms serve `marzipan batch`. Both write the same grid; a file written to a
// stream is OpenVDB's stream layout (io::Stream), which io::Stream reads back.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <span>
#include <string>

#include "engine/volume.hpp"

namespace marzipan {

inline constexpr const char* kColorGridName = "color";

// Writes the volume as a .vdb file (replacing it). Throws EngineError(InvalidArgument, "path").
void saveVdb(const Volume& vol, const std::string& path);
// Writes the volume as a .vdb stream to `out`.
void saveVdb(const Volume& vol, std::ostream& out);

// Reads the first float grid of a .vdb file into a new volume of `dims` (band as in Volume):
// voxel (i, j, k) takes the grid's value at index (i, j, k), clamped to +-band; a grid with
// another background scale still gives distances in its index space. Throws
// EngineError(Format, "file") for an unreadable file, one without a float grid, a grid whose
// active voxels or tiles reach outside [0, dims), or a non-finite value inside the domain.
Volume loadVdb(const std::string& path, Int3 dims, float band = Volume::kDefaultBand);
// The same from a stream holding a whole .vdb file (a client's upload), of file format version
// 222 to 224. OpenVDB is shown only the header and the grid to be read: every length it would
// trust before that grid's tree (names, metadata values, counts) is checked against the file's
// length first, later grids are never parsed, and a read past the end throws at once. The first
// float grid is found through the grid offsets of a file that has them (io::File writes them);
// a file without them (a stream) must have it first. Its colour grid is read the same way: with
// grid offsets wherever it lies, without them only right after the float grid (where saveVdb
// puts it). The caller bounds the stream's length:
// OpenVDB builds the grid's tree before it can be checked, and a tree takes at most about 33
// times the bytes that describe it (an internal node of 32 KiB per 1 KiB of masks), so the
// memory of a read is bounded by that multiple of the upload.
Volume loadVdb(std::istream& in, Int3 dims, float band = Volume::kDefaultBand);
// The same from a whole .vdb file in memory (a client's upload): the bytes OpenVDB is shown (the
// header and the one grid) are the only copy made of it. `maxBytes` bounds the volume's memory
// (Volume::memoryBytes, a session's max_volume_bytes): a grid's values become bricks one slab
// of bricks at a time, and once they pass it the read stops with EngineError(TooLarge, "file").
// A few hundred bytes (an empty tree whose background lies inside the band) would otherwise
// make every brick of the domain data before anything could compare it with the limit. The
// colours, once taken, count too (TooLarge when they pass it).
Volume loadVdb(std::span<const std::uint8_t> file, Int3 dims, float band = Volume::kDefaultBand,
               std::size_t maxBytes = SIZE_MAX);

}  // namespace marzipan
