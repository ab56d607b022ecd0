// PLY files, binary little-endian (conventions in mesh_format.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mesh_format.hpp"

namespace marzipan {

// Binary little-endian PLY: vertex x y z [nx ny nz] as float, face "list uchar uint".
std::vector<std::uint8_t> exportPly(const Mesh& m);

// Binary little-endian PLY with a "vertex" element (x, y, z and optional nx, ny, nz of any
// scalar type) and a "face" element with a vertex_indices list; other elements must have only
// scalar properties and are skipped.
Mesh parsePly(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
