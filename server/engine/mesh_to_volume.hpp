// A closed triangle mesh turned into a solid: placing it in the domain, and its signed distance
// field. Conventions in mesh_format.hpp and volume.hpp.
#pragma once

#include "geometry.hpp"
#include "marching_cubes.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

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
// - Vertex colours (Mesh::colors, sRGB bytes), when the mesh has them, become the volume's
//   colour channel: a band voxel takes the colour of its nearest surface point, the barycentric
//   mix of its nearest triangle's corner colours (of the bytes, rounded); every other voxel keeps
//   the base colour (kClayColor), and a colour change moving the surface later reaches them by
//   extension (Volume::extendChannels). Without colours the volume carries no channel at all.
// Throws EngineError(Format) for an empty, open, non-manifold or inconsistently oriented mesh,
// indices out of range or non-finite coordinates. Identical for any thread count.
Volume importMesh(const Mesh& m, Int3 dims, float band = Volume::kDefaultBand, ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
