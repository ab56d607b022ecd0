// glTF 2.0 binary (.glb) export of a triangle mesh, for Blender, three.js, game engines and any
// viewer that reads glTF, and import of the triangles such a file holds.
//
// Conventions: one scene, one node, one mesh with one indexed triangle primitive. Positions
// are vu as they are (glTF's unit is the metre: 1 vu becomes 1 m; glTF's +Y up is the volume's
// +y); triangles counter-clockwise seen from outside, as glTF wants. Indices are uint32;
// normals, when the mesh has them, are written as unit vectors (a zero normal is replaced by
// the area-weighted normal of the triangles around the vertex). Vertex colours, when the mesh
// has them, are COLOR_0 as float VEC3: glTF defines COLOR_0 in linear light, so each sRGB byte
// is decoded by the sRGB transfer function first (color_space.hpp); floats keep the dark shades
// apart that 8 linear bits would merge, and encoding them back to sRGB and rounding gives the
// bytes again. Little-endian whatever the host; every chunk is padded to 4 bytes (JSON with
// spaces, binary with zeros).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "marching_cubes.hpp"

namespace marzipan {

// Throws EngineError(InvalidArgument) for positions/indices not in threes, normals not one per
// vertex, indices out of range or non-finite positions; EngineError(TooLarge) past 4 GiB.
std::vector<std::uint8_t> exportGlb(const Mesh& m);

// The triangles of a .glb (glTF 2.0 binary with its buffer in the file's binary chunk): every
// primitive of every mesh (mode 4, triangles; POSITION float VEC3; indices, when present,
// unsigned integers) in file order, taken in vu as the accessors hold them: node transforms are
// not applied (Marzipan's own files have none). COLOR_0 (float, or normalized unsigned integers,
// VEC3 or VEC4, alpha ignored) is linear light and becomes sRGB bytes (color_space.hpp); the
// colours are kept only when every primitive has them. Normals are not read (import computes
// its own). Sparse accessors, external buffers and accessors without a buffer view are
// refused; every accessor is checked to lie inside its view and the chunk, and the JSON is
// parsed strictly with bounded nesting. Throws EngineError(Format) naming what is wrong.
Mesh parseGlb(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
