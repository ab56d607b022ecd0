// The grid's bounds, shown when the model nears them: whatever grows past the grid is cut off
// flat, so the sculptor should see where that happens before it does.
// Conventions: vu, y up; voxel centres run from 0 to n - 1 per axis, which is the box drawn;
// `bricks` is an iterable of {brick: [bx, by, bz], count, positions} as in render/splat-store.js,
// a brick's points lying within [8b - 2, 8b + 10) per axis (server/engine/splats.hpp).

const BRICK = 8;
const REACH_LO = -2;
const REACH_HI = 10;

// How close (vu) a surface point must come to a face of the grid for the box to show: about a
// default brush's radius, the distance at which a dab starts to be cut.
export const GRID_NEAR_VU = 8;

// True when some point lies within `margin` of a face of the grid of `size` voxels per side.
// Only bricks whose reach comes that close are searched, so a model in the middle costs one
// test per brick.
export function nearGridEdge(bricks, size, margin = GRID_NEAR_VU) {
  for (const b of bricks) {
    let close = false;
    for (let k = 0; k < 3; ++k) {
      const lo = BRICK * b.brick[k] + REACH_LO;
      const hi = BRICK * b.brick[k] + REACH_HI;
      if (lo < margin || hi > size[k] - 1 - margin) close = true;
    }
    if (!close) continue;
    const p = b.positions;
    for (let i = 0; i < 3 * b.count; i += 3)
      for (let k = 0; k < 3; ++k) if (p[i + k] < margin || p[i + k] > size[k] - 1 - margin) return true;
  }
  return false;
}

// The twelve edges of the grid's box, [[a, b], ...].
export function gridBoxEdges(size) {
  const hi = size.map((n) => n - 1);
  const corner = (i) => [i & 1 ? hi[0] : 0, i & 2 ? hi[1] : 0, i & 4 ? hi[2] : 0];
  const edges = [];
  for (let i = 0; i < 8; ++i)
    for (const bit of [1, 2, 4]) if (!(i & bit)) edges.push([corner(i), corner(i | bit)]);
  return edges;
}
