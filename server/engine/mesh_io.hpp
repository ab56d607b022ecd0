// Mesh files in and out, by format: one header per format (stl.hpp, obj.hpp, ply.hpp, gltf.hpp),
// what they share (mesh_format.hpp), and conversion of a closed triangle mesh into a signed
// distance volume (mesh_to_volume.hpp). This header includes them all and
// picks a format by MeshFormat. Conventions in mesh_format.hpp.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "gltf.hpp"
#include "mesh_format.hpp"
#include "mesh_to_volume.hpp"
#include "obj.hpp"
#include "ply.hpp"
#include "stl.hpp"

namespace marzipan {

// The file of m in `format` (OBJ as its text's bytes, Glb by exportGlb).
std::vector<std::uint8_t> exportMesh(const Mesh& m, MeshFormat format);

// The mesh in bytes of `format`.
Mesh parseMesh(std::span<const std::uint8_t> bytes, MeshFormat format);

}  // namespace marzipan
