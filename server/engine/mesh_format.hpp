// What every mesh file format shares: the format names, the limits and checks that apply to all
// of them, and writing a file. One file per format: stl.hpp, obj.hpp, ply.hpp, gltf.hpp;
// mesh_io.hpp picks one by MeshFormat; mesh_to_volume.hpp turns a mesh into a solid.
//
// Conventions: mesh coordinates are vu, taken as they are (voxel (i,j,k) at the point (i,j,k));
// triangles counter-clockwise seen from outside (see marching_cubes.hpp). Every byte layout is
// little-endian whatever the host. A buffer that cannot be decoded throws
// EngineError(ErrorKind::Format) naming what is wrong (and the line, for text formats); the
// parsers never read past the buffer and never allocate more than the buffer can describe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "marching_cubes.hpp"

namespace marzipan {

enum class MeshFormat { Stl, Obj, Ply, Glb };

// "stl", "obj", "ply", "glb".
std::optional<MeshFormat> meshFormatFromName(std::string_view name);

// Largest triangle count any parser accepts (a 3.4 GB binary STL).
inline constexpr std::size_t kMaxMeshTriangles = std::size_t(1) << 26;

// Every exporter first checks that m is well formed (positions and indices in threes, normals
// and colours none or one per vertex, indices in range, at most 2^32 - 1 triangles) and throws
// EngineError(field "mesh") otherwise: a bad mesh is the caller's mistake, not a file's.
void requireExportable(const Mesh& m);

// Writes bytes to a file (replacing it). Throws EngineError(InvalidArgument, "path") on failure.
void writeFile(const std::string& path, std::span<const std::uint8_t> bytes);
void writeFile(const std::string& path, std::string_view text);

}  // namespace marzipan
