// OpenVDB level-set files (.vdb) in and out; built only with -DMARZIPAN_WITH_OPENVDB=ON
// (Debian's libopenvdb-dev), which defines MARZIPAN_HAS_OPENVDB for code that uses it.
//
// Conventions: one FloatGrid named "surface", class level set, voxel size 1 (1 vu) and index
// (i, j, k) at the point (i, j, k), as in volume.hpp; background = the band half-width w;
// active voxels are those with |d| < w; inactive values carry the sign (-w inside, +w
// outside), as OpenVDB's level-set tools expect.
#pragma once

#include <string>

#include "engine/volume.hpp"

namespace marzipan {

// Writes the volume as a .vdb file (replacing it). Throws EngineError(InvalidArgument, "path").
void saveVdb(const Volume& vol, const std::string& path);

// Reads the first float grid of a .vdb file into a new volume of `dims` (band as in Volume):
// voxel (i, j, k) takes the grid's value at index (i, j, k), clamped to +-band; a grid with
// another background scale still gives distances in its index space. Throws
// EngineError(Format) for an unreadable file or one without a float grid.
Volume loadVdb(const std::string& path, Int3 dims, float band = Volume::kDefaultBand);

}  // namespace marzipan
