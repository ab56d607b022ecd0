// Triangle meshes of the solid's surface (the zero isosurface of the field), by marching cubes.
//
// Conventions: positions in vu (voxel (i,j,k) at the point (i,j,k)), stored as flat float
// triples; triangles are counter-clockwise seen from outside, so the right-hand normal points
// towards d > 0 (outward, like grad d). Cells are the unit cubes between 8 voxels; a vertex
// sits on every grid edge whose end voxels differ in sign (inside means d < 0), placed by
// linear interpolation of d, with the normalized interpolated central-difference gradient as
// its normal. Voxels outside the domain read +band, so a solid touching the domain's side is
// capped there and the mesh stays closed.
//
// Vertex colours (sRGB bytes, channels.hpp) come with the mesh when the volume carries colour:
// something painted, or a base colour other than kClayColor. A vertex takes the trilinear
// interpolation of the voxels' colour bytes at its position, rounded to the nearest byte; on its
// grid edge that is the two end voxels mixed by the same t that placed it. Trilinear rather than
// the nearest voxel because the paint tool keeps colour constant along the normals through the
// band (paint.hpp), so both end voxels name about the same surface point, and a painted border
// then shades over one edge instead of following whichever voxel is nearer, a staircase. A volume
// that carries no colour gives a mesh without colours, whose files are byte for byte those of
// before colour existed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

struct Mesh {
  std::vector<float> positions;        // x, y, z per vertex
  std::vector<float> normals;          // x, y, z per vertex, or empty
  std::vector<std::uint32_t> indices;  // three vertex indices per triangle
  std::vector<std::uint8_t> colors;    // r, g, b per vertex (sRGB), or empty

  std::size_t vertexCount() const { return positions.size() / 3; }
  std::size_t triangleCount() const { return indices.size() / 3; }
  Vec3 position(std::size_t v) const { return {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]}; }
  Vec3 normal(std::size_t v) const { return {normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]}; }
  Rgb8 color(std::size_t v) const { return {colors[3 * v], colors[3 * v + 1], colors[3 * v + 2]}; }
};

// Whether the volume's meshes carry vertex colours (see above).
bool carriesColor(const Volume& vol);

// The colour bytes of the volume at p by trilinear interpolation of its voxels' texels, each
// channel rounded to the nearest integer.
Rgb8 colorAt(const Volume& vol, Vec3 p);

// The closed, manifold, outward-oriented mesh of the zero isosurface.
// - One vertex per crossed grid edge, shared by every triangle around it (also across bricks).
// - Ambiguous cell faces (two diagonal inside corners) always keep the inside corners apart,
//   a rule that depends only on the face's four signs, so both cells sharing a face agree and
//   the mesh has no cracks or holes.
// - Only blocks of cells whose bricks hold both signs are visited (stored bricks are scanned
//   for their signs, uniform ones are not read).
// - The output (vertex and triangle order included) is identical for any number of threads.
//   Throws EngineError(TooLarge) past 2^32 - 1 vertices.
// - Colours as said above, when carriesColor(vol).
Mesh extractMesh(const Volume& vol, ThreadPool& pool = ThreadPool::serial());

// Surface area (vu^2) and enclosed signed volume (vu^3, by the divergence theorem: positive for
// an outward-oriented closed mesh).
double meshArea(const Mesh& m);
double meshVolume(const Mesh& m);

// V - E + F, counting the distinct undirected edges (2 for a sphere, 0 for a torus).
long long eulerCharacteristic(const Mesh& m);

// Edge census of a triangle mesh. A closed, consistently oriented, edge-manifold mesh has every
// undirected edge in exactly two triangles that run through it in opposite directions.
struct EdgeCheck {
  std::size_t edges = 0;
  std::size_t boundary = 0;     // edges in one triangle only
  std::size_t nonManifold = 0;  // edges in three or more triangles
  std::size_t misoriented = 0;  // edges in two triangles that run through it the same way
  std::size_t degenerate = 0;   // triangles that repeat a vertex index

  bool closedManifold() const { return boundary == 0 && nonManifold == 0 && misoriented == 0 && degenerate == 0; }
};
EdgeCheck checkEdges(const Mesh& m);

}  // namespace marzipan
