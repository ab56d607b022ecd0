// PLY files, binary little-endian (conventions in mesh_format.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mesh_format.hpp"

namespace marzipan {

// Binary little-endian PLY: vertex x y z [nx ny nz] as float [red green blue as uchar, sRGB,
// when the mesh has colours], face "list uchar uint".
std::vector<std::uint8_t> exportPly(const Mesh& m);

// Binary little-endian PLY with a "vertex" element (x, y, z and optional nx, ny, nz of any
// scalar type) and a "face" element with a vertex_indices list; other elements must have only
// scalar properties and are skipped. Vertex colours are kept when the vertices have all of red,
// green and blue: integers in 0..255 (uchar, as MeshLab and Blender write them) or floats in
// 0..1 (scaled by 255 and rounded); a value outside its range is refused. Alpha is ignored.
Mesh parsePly(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
