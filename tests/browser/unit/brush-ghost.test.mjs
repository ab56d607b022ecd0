// web-client/math/brush-ghost.js: what the brush cursor draws for each kind of tool.
import { test } from "node:test";
import assert from "node:assert/strict";

import { brushGhost } from "../../../web-client/math/brush-ghost.js";

const c = [10, 20, 30];

test("a brush: its ring in the tangent plane and an inner ring at radius × strength", () => {
  const g = brushGhost({ kind: "stroke", strength: 0.25 }, c, [0, 0, 1], 8);
  assert.deepEqual(g.rings, [
    { center: c, normal: [0, 0, 1], radius: 8, inner: false },
    { center: c, normal: [0, 0, 1], radius: 2, inner: true },
  ]);
  assert.deepEqual(g.segments, []);
  assert.equal(brushGhost({ kind: "stroke", strength: 1 }, c, [0, 0, 1], 8).rings.length, 1, "full strength: the rings coincide, one is drawn");
});

test("a CSG sphere: three great circles of the radius around the point", () => {
  const g = brushGhost({ kind: "click", shape: "sphere" }, c, [0, 1, 0], 5);
  assert.deepEqual(g.rings.map((r) => [r.normal, r.radius, r.center]), [[[1, 0, 0], 5, c], [[0, 1, 0], 5, c], [[0, 0, 1], 5, c]]);
});

test("a CSG box: the 12 edges of the cube of half side radius", () => {
  const g = brushGhost({ kind: "click", shape: "box" }, c, [0, 1, 0], 4);
  assert.equal(g.segments.length, 12);
  for (const [a, b] of g.segments) {
    const diff = a.map((v, i) => Math.abs(b[i] - v));
    assert.deepEqual([...diff].sort((x, y) => x - y), [0, 0, 8], "each edge is 2r long along one axis");
    for (const p of [a, b]) p.forEach((v, i) => assert.equal(Math.abs(v - c[i]), 4, "corners at ±r"));
  }
  const keys = new Set(g.segments.map(([a, b]) => JSON.stringify([a, b])));
  assert.equal(keys.size, 12, "no edge twice");
});

test("a CSG cylinder along y: end circles at ±r and four side lines", () => {
  const g = brushGhost({ kind: "click", shape: "cylinder", axis: 1 }, c, [1, 0, 0], 3);
  assert.deepEqual(g.rings.map((r) => [r.center, r.normal, r.radius]), [[[10, 17, 30], [0, 1, 0], 3], [[10, 23, 30], [0, 1, 0], 3]]);
  assert.equal(g.segments.length, 4);
  for (const [a, b] of g.segments) {
    assert.equal(a[1], 17);
    assert.equal(b[1], 23);
    assert.equal(Math.hypot(a[0] - 10, a[2] - 30), 3, "on the cylinder's side");
  }
});
