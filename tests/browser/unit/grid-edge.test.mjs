// web-client/math/grid-edge.js: when the model nears the grid's faces, and the box drawn then.
import { test } from "node:test";
import assert from "node:assert/strict";

import { GRID_NEAR_VU, gridBoxEdges, nearGridEdge } from "../../../web-client/math/grid-edge.js";

function brickOf(points) {
  const b = points[0].map((c) => Math.floor(c / 8));
  return { brick: b, count: points.length, positions: Float32Array.from(points.flat()) };
}

test("a model in the middle of the grid is not near its edge", () => {
  const bricks = [brickOf([[60, 64, 64]]), brickOf([[20, 30, 100]])];
  assert.equal(nearGridEdge(bricks, [128, 128, 128]), false);
});

test("a point closer than the margin to any face is near, on either side of every axis", () => {
  const size = [128, 96, 64];
  for (let k = 0; k < 3; ++k) {
    const low = [40, 40, 30];
    low[k] = GRID_NEAR_VU - 0.5;
    assert.equal(nearGridEdge([brickOf([low])], size), true, `low face of axis ${k}`);
    const high = [40, 40, 30];
    high[k] = size[k] - 1 - GRID_NEAR_VU + 0.5;
    assert.equal(nearGridEdge([brickOf([high])], size), true, `high face of axis ${k}`);
    const inside = [40, 40, 30];
    inside[k] = size[k] - 1 - GRID_NEAR_VU - 0.5;
    assert.equal(nearGridEdge([brickOf([inside])], size), false, `just inside on axis ${k}`);
  }
});

test("a brick near the edge whose points stay clear is not near", () => {
  // brick x = 1 reaches down to 6 vu, but its only point is at x = 12
  assert.equal(nearGridEdge([brickOf([[12, 60, 60]])], [128, 128, 128]), false);
});

test("the box is the twelve edges between the voxel centres 0 and n - 1", () => {
  const edges = gridBoxEdges([4, 5, 6]);
  assert.equal(edges.length, 12);
  for (const [a, b] of edges) {
    const differing = [0, 1, 2].filter((k) => a[k] !== b[k]);
    assert.equal(differing.length, 1);
    const k = differing[0];
    assert.deepEqual([a[k], b[k]].sort(), [0, [3, 4, 5][k]]);
  }
  const corners = new Set(edges.flat().map((p) => p.join()));
  assert.equal(corners.size, 8);
});
