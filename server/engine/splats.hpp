// Foot-point splats (docs/method.md §6): the point cloud that shows the solid, produced per
// brick so that an edit re-extracts only the bricks around the ones it replaced.
//
// Conventions: sign and units as in volume.hpp (d < 0 inside, vu, voxel (i,j,k) at (i,j,k)).
// A voxel p of the domain is next to the surface when a 6-neighbour has the other sign
// (d < 0 versus d >= 0; outside the domain reads +band) or |d(p)| < kSurfaceNear. It yields
// exactly one splat: the unit normal n = g/|g|, g the central-difference gradient, and the
// foot point q = p - d(p) n, clamped to the brick's encodable range [o - 2, o + 10) per axis
// (o = 8 * brick); only fields that are not distances there (a solid cut by the domain's edge,
// bricks of -band next to bricks of +band) reach the clamp. Where g vanishes (a sheet thinner
// than a voxel) the splat stays at p with normal +z. Splats of a brick come in voxel order
// (x fastest, then y, then z), so extraction is deterministic and independent of threads.
// Channels (channels.hpp): a brick that carries a BrickPaint gives each splat the texel of its
// voxel p (BrickSplats::texels, one per point); a brick without one gives none, its points being
// the volume's base colour with weight 0.
//
// The splat of voxel p reads d(p), p's six neighbours and p's texel, so after an edit only a
// surface voxel (in the state before or after it) that reads a changed value can change a splat,
// in its changed brick or in a face neighbour: bricksAroundChanges() lists what to re-extract.
//
// The wire encoding of splats is protocol/cpp/splats.hpp.
#pragma once

#include <vector>

#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"
#include "protocol/cpp/values.hpp"  // Splat, BrickSplats, the encodable range

namespace marzipan {

// |d| below which a voxel yields a splat even without a sign change among its neighbours: half
// the voxel diagonal, so every voxel whose cell the surface may cross is kept.
inline constexpr float kSurfaceNear = 0.87f;

// The splats of one brick (any brick of brickDims(); throws EngineError OutOfDomain otherwise).
BrickSplats extractBrickSplats(const Volume& vol, Int3 brick);

// The splats of the given bricks, in the given order, empty bricks included (a delta). Every
// coordinate is checked before any work starts.
std::vector<BrickSplats> extractSplats(const Volume& vol, const std::vector<Int3>& bricks,
                                       ThreadPool& pool = ThreadPool::serial());

// Every brick that has splats, in z, y, x order (a full picture).
std::vector<BrickSplats> extractAllSplats(const Volume& vol, ThreadPool& pool = ThreadPool::serial());

// The bricks whose splats may differ after `changes` (vol holding either side of them: the list is
// the same after the edit and after its undo): of each changed brick and its six face neighbours
// within vol.brickDims(), those with a voxel p in the domain that is next to the surface before
// or after and of which p or a 6-neighbour changed bit for bit, and changed bricks whose channels'
// buffer (BrickRef::paint) changed. Every brick left out extracts the same block in both states.
// Sorted z, y, x and without duplicates. A list naming a brick twice gets the changed bricks and
// all their face neighbours.
std::vector<Int3> bricksAroundChanges(const Volume& vol, const std::vector<BrickChange>& changes);

}  // namespace marzipan
