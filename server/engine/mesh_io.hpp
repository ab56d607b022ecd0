// Mesh files in and out: binary STL, OBJ and binary PLY export; STL (binary or ASCII), OBJ and
// binary PLY parsing; and conversion of a closed triangle mesh into a signed distance volume.
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
#include <vector>

#include "geometry.hpp"
#include "marching_cubes.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

enum class MeshFormat { Stl, Obj, Ply, Glb };

// "stl", "obj", "ply", "glb" (glb is written only: gltf.hpp).
std::optional<MeshFormat> meshFormatFromName(std::string_view name);

// Largest triangle count any parser accepts (a 3.4 GB binary STL).
inline constexpr std::size_t kMaxMeshTriangles = std::size_t(1) << 26;

// --- export ----------------------------------------------------------------------------------
// Every exporter first checks that m is well formed (positions and indices in threes, normals
// none or one per vertex, indices in range, at most 2^32 - 1 triangles) and throws
// EngineError(field "mesh") otherwise: a bad mesh is the caller's mistake, not a file's.
void requireExportable(const Mesh& m);
// Binary STL: 80-byte header, uint32 count, per triangle the unit face normal (zero when
// degenerate), three vertices and a zero uint16.
std::vector<std::uint8_t> exportStl(const Mesh& m);
// OBJ: "v x y z" and, when the mesh has normals, "vn" lines and faces "f a//a b//b c//c"
// (1-based); floats with 9 significant digits, so parsing gives back the same floats.
std::string exportObj(const Mesh& m);
// Binary little-endian PLY: vertex x y z [nx ny nz] as float, face "list uchar uint".
std::vector<std::uint8_t> exportPly(const Mesh& m);
// Glb: exportGlb (gltf.hpp).
std::vector<std::uint8_t> exportMesh(const Mesh& m, MeshFormat format);

// Writes bytes to a file (replacing it). Throws EngineError(InvalidArgument, "path") on failure.
void writeFile(const std::string& path, std::span<const std::uint8_t> bytes);
void writeFile(const std::string& path, std::string_view text);

// --- parsing ---------------------------------------------------------------------------------
// OBJ: "v" and "f" statements (polygons are fanned into triangles, negative indices count back
// from the last vertex); normals are kept only when every face uses normal index = vertex index.
// Other statements (vt, g, o, s, usemtl, ...) are ignored.
Mesh parseObj(std::string_view text);
// STL, binary (when the size is exactly 84 + 50 * count) or ASCII (starting with "solid").
// Identical corner positions are merged into shared vertices (in order of first use); the file's
// facet normals are not kept (the result has no normals).
Mesh parseStl(std::span<const std::uint8_t> bytes);
// Binary little-endian PLY with a "vertex" element (x, y, z and optional nx, ny, nz of any
// scalar type) and a "face" element with a vertex_indices list; other elements must have only
// scalar properties and are skipped.
Mesh parsePly(std::span<const std::uint8_t> bytes);
// Glb is not read: EngineError(Format).
Mesh parseMesh(std::span<const std::uint8_t> bytes, MeshFormat format);

// --- import ----------------------------------------------------------------------------------
// Scales (uniformly) and moves a copy of the mesh so that its bounding box is centred in the
// domain with `margin` vu of air around it on the tightest axis.
Mesh fitMeshToDomain(const Mesh& m, Int3 dims, double margin);

// A new volume (dims, band as in Volume's constructor) holding the signed distance to a closed
// triangle mesh placed as-is in vu coordinates (use fitMeshToDomain to place it first); parts
// outside the domain are cut off like any solid there.
// - The mesh must be closed and edge-manifold after merging vertices at identical positions:
//   every edge in exactly two triangles, running through it in opposite directions. Triangles
//   that repeat a vertex are dropped. A mesh turned inside out (negative volume) is flipped.
// - Band voxels get the exact distance to the nearest triangle; the sign comes from the
//   angle-weighted pseudonormal of the nearest feature (face, edge or vertex). Voxels beyond the
//   band take the sign of a neighbour (no surface can pass between them); the first voxel of the
//   domain, when it is beyond the band, asks the generalized winding number.
// Throws EngineError(Format) for an empty, open, non-manifold or inconsistently oriented mesh,
// indices out of range or non-finite coordinates. Identical for any thread count.
Volume importMesh(const Mesh& m, Int3 dims, float band = Volume::kDefaultBand, ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
