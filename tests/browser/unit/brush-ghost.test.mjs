// web-client/math/brush-ghost.js: what the brush cursor draws for each kind of tool, warps and
// the plane of flatten and contrast included.
import { test } from "node:test";
import assert from "node:assert/strict";

import { arcSegments, arrowSegments, brushGhost, planeGhost, PLANE_ALPHA, TWIST_ARC, warpGhost } from "../../../web-client/math/brush-ghost.js";

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

const near = (a, b, eps = 1e-9) => a.every((v, i) => Math.abs(v - b[i]) <= eps);
const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);

test("an arrow: its shaft from a to b, two head sides of the given length back from b, open in the plane facing the camera", () => {
  const segs = arrowSegments([0, 0, 0], [10, 0, 0], [0, 0, 1], 2);
  assert.equal(segs.length, 3);
  assert.deepEqual(segs[0], [[0, 0, 0], [10, 0, 0]]);
  for (const [from, to] of segs.slice(1)) {
    assert.deepEqual(from, [10, 0, 0]);
    assert.ok(Math.abs(dist(from, to) - 2) < 1e-12, "side length");
    assert.ok(to[0] < 10 && to[2] === 0, "back along the shaft, in the plane z = 0");
  }
  assert.ok(Math.abs(segs[1][1][1] + segs[2][1][1]) < 1e-12 && segs[1][1][1] !== 0, "symmetric about the shaft");
  assert.ok(Math.abs(dist(...arrowSegments([0, 0, 0], [1, 0, 0], [0, 0, 1], 5)[1]) - 0.5) < 1e-12, "the head at most half a short arrow");
  assert.deepEqual(arrowSegments([1, 1, 1], [1, 1, 1], [0, 0, 1], 2), [], "no arrow for no move");
});

test("an arc turns right-handed about its normal by the angle, on its radius", () => {
  const segs = arcSegments([1, 2, 3], [0, 0, 1], 4, [1, 0, 5], Math.PI / 2);
  assert.ok(near(segs[0][0], [5, 2, 3]), "starts along `from`'s part in the plane");
  assert.ok(near(segs.at(-1)[1], [1, 6, 3]), "a quarter turn about +z takes +x to +y");
  for (const [a, b] of segs) {
    assert.ok(Math.abs(dist(a, [1, 2, 3]) - 4) < 1e-12 && Math.abs(dist(b, [1, 2, 3]) - 4) < 1e-12, "on the circle");
    assert.ok(dist(a, b) < 4 * (Math.PI / 40), "in short chords");
  }
  assert.ok(near(arcSegments([0, 0, 0], [0, 0, 1], 1, [1, 0, 0], -Math.PI).at(-1)[1], [-1, 0, 0]), "negative angles turn the other way");
  assert.ok(near(arcSegments([0, 0, 0], [0, 0, 1], 1, [1, 0, 0], -Math.PI / 2).at(-1)[1], [0, -1, 0]));
});

test("grab: the ring at the anchor, an arrow from it to the pointer's point, the ring again where it goes", () => {
  const anchor = [10, 20, 30];
  const point = [40, 20, 30];
  for (const name of ["grab"]) {
    assert.deepEqual(warpGhost({ name, dabs: "anchored" }, { anchor, anchorNormal: [1, 0, 0], point: null, viewNormal: [0, 0, 1] }, 8), {
      rings: [{ center: anchor, normal: [1, 0, 0], radius: 8, inner: false }],
      segments: [],
    }, "before the pointer moves: the ring");
    const g = warpGhost({ name, dabs: "anchored" }, { anchor, anchorNormal: [1, 0, 0], point, viewNormal: [0, 0, 1] }, 8);
    assert.deepEqual(g.segments[0], [anchor, point], "the shaft runs from the anchor to the point");
    assert.equal(g.segments.length, 3);
    for (const [from] of g.segments.slice(1)) assert.deepEqual(from, point, "the head at the point");
    assert.deepEqual(g.rings.map((r) => [r.center, r.radius, r.inner]), [[anchor, 8, false], [point, 8, true]]);
  }
});

test("snake hook: the path it went, the arrow's head at the pointer's point", () => {
  const path = [[0, 0, 0], [2, 0, 0], [4, 0, 0], [4, 2, 0]];
  const g = warpGhost({ name: "snake_hook", dabs: "path" }, { anchor: path[0], anchorNormal: [0, 0, 1], point: [4, 3, 0], path, viewNormal: [0, 0, 1] }, 4);
  assert.deepEqual(g.segments.slice(0, 4), [[path[0], path[1]], [path[1], path[2]], [path[2], path[3]], [path[3], [4, 3, 0]]]);
  assert.equal(g.segments.length, 6, "and the head's two sides");
  const atEnd = warpGhost({ name: "snake_hook", dabs: "path" }, { anchor: path[0], anchorNormal: [0, 0, 1], point: [4, 2, 0], path, viewNormal: [0, 0, 1] }, 4);
  assert.deepEqual(atEnd.segments.slice(0, 3), [[path[0], path[1]], [path[1], path[2]], [path[2], path[3]]], "a point on the path's end adds no stretch");
  assert.equal(atEnd.segments.length, 5);
});

test("twist: an arc about the anchor's normal of s pi/2, s the drag along the direction in radii; scale: the ring times 2^s within 1/4 to 4; pinch: times e^-(s/2) within e^-1 to e", () => {
  const anchor = [0, 0, 0];
  const n = [0, 0, 1];
  const view = { anchor, anchorNormal: n, direction: [1, 0, 0], viewNormal: [0, 0, 1] };
  // dragged 8 vu right at radius 8: s = 1, a quarter turn
  const twist = warpGhost({ name: "twist", dabs: "anchored" }, { ...view, point: [8, 3, 0] }, 8);
  const arc = twist.segments.slice(0, -2);
  const r = TWIST_ARC * 8;
  assert.ok(near(arc[0][0], [r, 0, 0]), "the arc starts along the direction");
  assert.ok(near(arc.at(-1)[1], [0, r, 0]), "and ends a quarter turn on");
  assert.deepEqual(twist.segments.at(-1)[0], arc.at(-1)[1], "its head at the arc's end");
  for (const side of twist.segments.slice(-2)) assert.ok(Math.abs(dist(...side) - 0.15 * 8) < 1e-9, "a head of 0.15 radius, however short the arc's chords");
  const back = warpGhost({ name: "twist", dabs: "anchored" }, { ...view, point: [-4, 0, 0] }, 8).segments.slice(0, -2);
  assert.ok(near(back.at(-1)[1], [r * Math.cos(-Math.PI / 4), r * Math.sin(-Math.PI / 4), 0]), "dragging left: the other way, s = -1/2");
  const scale = warpGhost({ name: "scale", dabs: "anchored" }, { ...view, point: [8, 0, 0] }, 8);
  assert.deepEqual(scale.rings.map((x) => x.radius), [8, 16], "s = 1 doubles");
  assert.deepEqual(scale.segments, []);
  assert.equal(warpGhost({ name: "scale", dabs: "anchored" }, { ...view, point: [-8, 0, 0] }, 8).rings[1].radius, 4, "s = -1 halves");
  assert.equal(warpGhost({ name: "scale", dabs: "anchored" }, { ...view, point: [80, 0, 0] }, 8).rings[1].radius, 32, "at most 4 times");
  assert.equal(warpGhost({ name: "scale", dabs: "anchored" }, { ...view, point: [-80, 0, 0] }, 8).rings[1].radius, 2, "at least a quarter");
  const pinch = (x) => warpGhost({ name: "pinch", dabs: "anchored" }, { ...view, point: [x, 0, 0] }, 8).rings[1].radius;
  assert.ok(Math.abs(pinch(8) - 8 * Math.exp(-0.5)) < 1e-12, "s = 1: a = 1/2 draws in by e^-1/2");
  assert.ok(Math.abs(pinch(-8) - 8 * Math.exp(0.5)) < 1e-12, "s = -1 spreads");
  assert.ok(Math.abs(pinch(80) - 8 * Math.exp(-1)) < 1e-12 && Math.abs(pinch(-80) - 8 * Math.E) < 1e-12, "a within -1 to 1");
});

test("elastic grab also shows the ball of 3 radii its Kelvinlet changes", () => {
  const g = warpGhost({ name: "elastic_grab", dabs: "anchored" }, { anchor: [0, 0, 0], anchorNormal: [0, 1, 0], point: [5, 0, 0], viewNormal: [0, 0, 1] }, 6);
  assert.deepEqual(g.rings.map((r) => [r.center, r.radius, r.inner]), [[[0, 0, 0], 6, false], [[0, 0, 0], 18, true], [[5, 0, 0], 6, true]]);
});

test("flatten and contrast: the server's plane as a translucent disc of the radius (a ring of radius r/2, r wide) and its rim", () => {
  const g = planeGhost({ point: [5, 6, 7], normal: [0, 2, 0] }, 10);
  assert.deepEqual(g.rings, [
    { center: [5, 6, 7], normal: [0, 1, 0], radius: 5, width: 10, inner: true, alpha: PLANE_ALPHA },
    { center: [5, 6, 7], normal: [0, 1, 0], radius: 10, inner: false },
  ]);
  const [disc] = g.rings;
  assert.equal(disc.radius - disc.width / 2, 0, "filled to the centre");
  assert.equal(disc.radius + disc.width / 2, 10, "out to the radius");
});
