// web-client/math/splat-pick.js: the nearest front-facing splat disc along a ray.
import { test } from "node:test";
import assert from "node:assert/strict";

import { pickSplats } from "../../../web-client/math/splat-pick.js";

// Bricks of points on a sphere, as a splat buffer would have them: one point per surface
// voxel, brick = floor(voxel / 8).
function sphereBricks(center, radius) {
  const map = new Map();
  const r = Math.ceil(radius) + 1;
  for (let z = center[2] - r; z <= center[2] + r; ++z)
    for (let y = center[1] - r; y <= center[1] + r; ++y)
      for (let x = center[0] - r; x <= center[0] + r; ++x) {
        const d = Math.hypot(x - center[0], y - center[1], z - center[2]);
        if (Math.abs(d - radius) > 0.87) continue;
        const n = [(x - center[0]) / d, (y - center[1]) / d, (z - center[2]) / d];
        const b = [x >> 3, y >> 3, z >> 3];
        const key = b.join();
        if (!map.has(key)) map.set(key, { brick: b, p: [], n: [] });
        const e = map.get(key);
        e.p.push(...n.map((v, i) => center[i] + radius * v));
        e.n.push(...n);
      }
  return [...map.values()].map((e) => ({ brick: e.brick, count: e.p.length / 3, positions: new Float32Array(e.p), normals: new Float32Array(e.n) }));
}

test("a ray towards a sphere hits its near side, within the disc radius", () => {
  const bricks = sphereBricks([40, 40, 40], 20);
  for (const dir of [[0, 0, -1], [1, 0, 0], [0, -1, 0], [0.6, -0.48, 0.64]]) {
    const len = Math.hypot(...dir);
    const d = dir.map((v) => v / len);
    const origin = [40 - 100 * d[0], 40 - 100 * d[1], 40 - 100 * d[2]];
    const hit = pickSplats(bricks, origin, d, 0.8);
    assert.ok(hit, `a ray along ${d} hits`);
    assert.ok(Math.abs(hit.t - 80) < 1, `t = ${hit.t}, expected about 80`);
    assert.ok(Math.abs(Math.hypot(hit.point[0] - 40, hit.point[1] - 40, hit.point[2] - 40) - 20) < 0.8);
    assert.ok(hit.normal[0] * d[0] + hit.normal[1] * d[1] + hit.normal[2] * d[2] < -0.9, "the near side faces the ray");
  }
});

test("rays that pass beside the sphere, point away or start past it miss", () => {
  const bricks = sphereBricks([40, 40, 40], 20);
  assert.equal(pickSplats(bricks, [40, 40, 140], [0, 0.2425, -0.9701], 0.8), null, "beside");
  assert.equal(pickSplats(bricks, [40, 40, 140], [0, 0, 1], 0.8), null, "away");
  // From inside the sphere, the inner side faces away: the discs are not drawn there either.
  assert.equal(pickSplats(bricks, [40, 40, 40], [0, 0, 1], 0.8), null, "from inside");
});

test("axis-parallel rays and empty bricks are handled", () => {
  const bricks = sphereBricks([20, 20, 20], 10);
  bricks.push({ brick: [2, 2, 9], count: 0, positions: new Float32Array(0), normals: new Float32Array(0) });
  const hit = pickSplats(bricks, [20, 20, 0], [0, 0, 1], 0.8);
  assert.ok(hit && Math.abs(hit.point[2] - 10) < 0.5, JSON.stringify(hit));
  assert.equal(pickSplats([], [0, 0, 0], [0, 0, 1], 0.8), null);
});

test("a hit carries the colour of the disc it hit; bricks without colours give none", () => {
  // Colour each point by the sign of its x: red on the +x half, green elsewhere.
  const bricks = sphereBricks([40, 40, 40], 20).map((b) => {
    const colors = new Uint8Array(4 * b.count);
    for (let k = 0; k < b.count; ++k) colors.set(b.positions[3 * k] > 40 ? [200, 20, 10, 0] : [10, 200, 20, 255], 4 * k);
    return { ...b, colors };
  });
  assert.deepEqual(pickSplats(bricks, [140, 40, 40], [-1, 0, 0], 0.8).color, [200, 20, 10]);
  assert.deepEqual(pickSplats(bricks, [-60, 40, 40], [1, 0, 0], 0.8).color, [10, 200, 20]);
  assert.equal(pickSplats(sphereBricks([40, 40, 40], 20), [140, 40, 40], [-1, 0, 0], 0.8).color, null);
});
