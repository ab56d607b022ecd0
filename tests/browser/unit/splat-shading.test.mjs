// web-client/math/splat-shading.js: the normal gradients of splat discs, fitted to their
// neighbours, on point sets whose surfaces are known exactly (a plane, a sphere, a cylinder, a
// crease), and the store's upkeep of them when a neighbouring brick changes.
import { test } from "node:test";
import assert from "node:assert/strict";

import { MAX_GRADIENT, discFrame, normalGradients } from "../../../web-client/math/splat-shading.js";
import { SplatStore, brickKey } from "../../../web-client/render/splat-store.js";

// An entry of brick `brick` holding the points [[x, y, z, nx, ny, nz], ...].
function entry(brick, points) {
  return {
    brick,
    count: points.length,
    positions: Float32Array.from(points.flatMap((p) => p.slice(0, 3))),
    normals: Float32Array.from(points.flatMap((p) => p.slice(3))),
  };
}

// Foot points of the voxels of brick `brick` within 0.87 vu of the surface of signed distance
// `sdf` (gradient `normal`), as the server makes them: q = p - d n.
function footPoints(brick, sdf, normal) {
  const points = [];
  for (let z = 8 * brick[2]; z < 8 * brick[2] + 8; ++z)
    for (let y = 8 * brick[1]; y < 8 * brick[1] + 8; ++y)
      for (let x = 8 * brick[0]; x < 8 * brick[0] + 8; ++x) {
        const d = sdf([x, y, z]);
        if (Math.abs(d) >= 0.87) continue;
        const n = normal([x, y, z]);
        points.push([x - d * n[0], y - d * n[1], z - d * n[2], ...n]);
      }
  return points;
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const gradientsOf = (g, i) => [[...g.slice(6 * i, 6 * i + 3)], [...g.slice(6 * i + 3, 6 * i + 6)]];

test("the disc frame is the shader's: t = normalize(h x n), b = n x t", () => {
  const [t, b] = discFrame([0, 0, 1]);
  assert.deepEqual(t, [1, 0, 0]);
  assert.deepEqual(b, [0, 1, 0]);
  const [t2, b2] = discFrame([0, 1, 0]); // |n.y| >= 0.9: h = +x
  assert.deepEqual(t2, [0, 0, 1]);
  assert.deepEqual(b2, [1, 0, 0]);
});

test("a flat plane: every normal constant, no gradient", () => {
  const e = entry([1, 1, 1], footPoints([1, 1, 1], (p) => p[1] - 12.3, () => [0, 1, 0]));
  assert.ok(e.count >= 64);
  assert.equal(normalGradients(e, [e]), null);
});

test("a sphere of radius 6: dn/du = t / 6 and dn/dv = b / 6 at every disc", () => {
  const c = [12, 12, 12 - 6]; // the brick (1,1,1) holds the sphere's top
  const sdf = (p) => Math.hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]) - 6;
  const normal = (p) => {
    const l = Math.hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
    return [(p[0] - c[0]) / l, (p[1] - c[1]) / l, (p[2] - c[2]) / l];
  };
  const e = entry([1, 1, 1], footPoints([1, 1, 1], sdf, normal));
  const g = normalGradients(e, [e]);
  let worst = 0, checked = 0;
  for (let i = 0; i < e.count; ++i) {
    const n = [...e.normals.slice(3 * i, 3 * i + 3)];
    const [t, b] = discFrame(n);
    const [gu, gv] = gradientsOf(g, i);
    // On a sphere the normal is (x - c) / R: its derivative along any tangent is that tangent / R.
    const p = [...e.positions.slice(3 * i, 3 * i + 3)];
    if (p[0] < 9.6 || p[0] > 14.4 || p[1] < 9.6 || p[1] > 14.4 || p[2] < 9.6) continue; // neighbours all round, in the brick
    for (let k = 0; k < 3; ++k) worst = Math.max(worst, Math.abs(gu[k] - t[k] / 6), Math.abs(gv[k] - b[k] / 6));
    ++checked;
  }
  assert.ok(checked > 10, `${checked} discs with neighbours all round`);
  assert.ok(worst < 0.01, `the fit is off by ${worst} per vu (exact: 1/6 = 0.167)`);
});

test("a cylinder of radius 2 along z: the normal turns at 1/2 per vu around it and not at all along it", () => {
  const sdf = (p) => Math.hypot(p[0] - 12, p[1] - 12) - 2;
  const normal = (p) => {
    const l = Math.hypot(p[0] - 12, p[1] - 12);
    return [(p[0] - 12) / l, (p[1] - 12) / l, 0];
  };
  const e = entry([1, 1, 1], footPoints([1, 1, 1], sdf, normal));
  const g = normalGradients(e, [e]);
  for (let i = 0; i < e.count; ++i) {
    const p = [...e.positions.slice(3 * i, 3 * i + 3)];
    if (p[2] < 10 || p[2] > 13) continue; // away from the brick's ends
    const n = [...e.normals.slice(3 * i, 3 * i + 3)];
    const [t, b] = discFrame(n);
    const [gu, gv] = gradientsOf(g, i);
    const around = [-n[1], n[0], 0]; // the tangent around the axis
    // the derivative of n along a tangent direction s is (s . around) around / 2
    for (const [s, grad] of [[t, gu], [b, gv]]) {
      const want = around.map((a) => (dot(s, around) * a) / 2);
      for (let k = 0; k < 3; ++k) assert.ok(Math.abs(grad[k] - want[k]) < 0.03, `disc at ${p}: ${grad} vs ${want}`);
    }
  }
});

test("a 90 degree crease: the discs next to it turn towards the other face, clamped to MAX_GRADIENT; far from it, flat", () => {
  // The solid x < 12 and y < 12: face A (y = 12, normal +y), face B (x = 12, normal +x).
  const points = [];
  for (let z = 8.5; z < 16; ++z) {
    for (let x = 8.5; x < 12; ++x) points.push([x, 12, z, 0, 1, 0]);
    for (let y = 8.5; y < 12; ++y) points.push([12, y, z, 1, 0, 0]);
  }
  const e = entry([1, 1, 1], points);
  const g = normalGradients(e, [e]);
  for (let i = 0; i < e.count; ++i) {
    const [x, y] = [e.positions[3 * i], e.positions[3 * i + 1]];
    const n = [...e.normals.slice(3 * i, 3 * i + 3)];
    const [t, b] = discFrame(n);
    const [gu, gv] = gradientsOf(g, i);
    // the change of the normal per vu towards the crease (+x on face A, +y on face B)
    const toward = y === 12 ? [1, 0, 0] : [0, 1, 0];
    const rate = gu.map((v, k) => dot(t, toward) * v + dot(b, toward) * gv[k]);
    const far = y === 12 ? 12 - x : 12 - y;
    if (far > 1.6) {
      assert.ok(rate.every((v) => v === 0) || rate.every((v) => Math.abs(v) < 1e-9), `no other face within reach at ${far} vu`);
      continue;
    }
    const other = y === 12 ? [1, -1, 0] : [-1, 1, 0]; // the other face's normal minus this one's
    if (far < 1) assert.ok(dot(rate, other) > 0, `disc ${far} vu from the crease turns towards the other face: ${rate}`);
    else assert.ok(dot(rate, other) >= 0, `disc ${far} vu from the crease does not turn away from it: ${rate}`);
    assert.ok([...gu, ...gv].every((v) => Math.abs(v) <= MAX_GRADIENT), "clamped");
    assert.equal(dot(rate, [0, 0, 1]), 0, "and not along the crease");
  }
});

test("the store fits a brick's gradients with its neighbours' points and refits a neighbour that changed", () => {
  const c = [16, 12, 12 - 6];
  const sdf = (p) => Math.hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]) - 6;
  const normal = (p) => {
    const l = Math.hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
    return [(p[0] - c[0]) / l, (p[1] - c[1]) / l, (p[2] - c[2]) / l];
  };
  const a = entry([1, 1, 1], footPoints([1, 1, 1], sdf, normal));
  const b = entry([2, 1, 1], footPoints([2, 1, 1], sdf, normal));
  const alone = normalGradients(a, [a]);
  const together = normalGradients(a, [a, b]);
  assert.notDeepEqual(alone, together, "the discs at the brick's +x face see the next brick's points");

  const store = new SplatStore();
  store.applyFull({ bricks: [a] }, 1);
  assert.deepEqual(store.bricks.get(brickKey(a.brick)).gradients, alone);
  store.takeChanges();
  store.applyDelta({ bricks: [b] }, 2);
  assert.deepEqual(store.bricks.get(brickKey(a.brick)).gradients, together);
  assert.equal(store.takeChanges().writes.length, 2, "the new brick and its neighbour whose gradients changed");
  store.applyDelta({ bricks: [{ brick: [2, 1, 1], count: 0 }] }, 3);
  assert.deepEqual(store.bricks.get(brickKey(a.brick)).gradients, alone, "the neighbour gone: as before");
  assert.equal(store.takeChanges().writes.length, 1);
  store.setVaryNormals(false);
  assert.equal(store.bricks.get(brickKey(a.brick)).gradients, null);
  assert.equal(store.takeChanges().repack, true);
});
