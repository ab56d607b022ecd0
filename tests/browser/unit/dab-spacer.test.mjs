// web-client/math/dab-spacer.js: dabs evenly spaced along the surface path of a drag.
import { test } from "node:test";
import assert from "node:assert/strict";

import { DabSpacer } from "../../../web-client/math/dab-spacer.js";
import { distance } from "../../../web-client/math/vec3.js";

test("the first hit is a dab, then one every `spacing` vu along the path", () => {
  const s = new DabSpacer(2);
  const dabs = [];
  for (let x = 0; x <= 20; x += 0.7) dabs.push(...s.add([x, 5, 5], [x * 10, 50], 1));
  assert.deepEqual(dabs[0].point, [0, 5, 5]);
  assert.equal(dabs.length, 1 + Math.floor(19.6 / 2));
  for (let i = 1; i < dabs.length; ++i) assert.ok(Math.abs(distance(dabs[i].point, dabs[i - 1].point) - 2) < 1e-9);
});

test("spacing holds around corners, measured along the path", () => {
  const s = new DabSpacer(1.5);
  const path = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [-3, 2, 0]];
  const dabs = path.flatMap((p) => s.add(p, [p[0], p[1]], 1));
  // Path length 1 + 1 + 1 + 1 + 3 = 7: dabs at 0, 1.5, 3, 4.5, 6.
  assert.equal(dabs.length, 5);
  assert.deepEqual(dabs[1].point, [1, 0.5, 0]);
  assert.deepEqual(dabs[2].point, [1, 2, 0]);
  assert.deepEqual(dabs[3].point, [-0.5, 2, 0]);
});

test("screen position and pressure are interpolated with the point", () => {
  const s = new DabSpacer(1);
  s.add([0, 0, 0], [100, 100], 0.2);
  const dabs = s.add([4, 0, 0], [140, 100], 1);
  assert.equal(dabs.length, 4);
  assert.deepEqual(dabs[1].screen, [120, 100]);
  assert.ok(Math.abs(dabs[1].pressure - 0.6) < 1e-12);
});

test("a miss or a jump starts a new path instead of filling the gap", () => {
  const s = new DabSpacer(1, 5);
  assert.equal(s.add([0, 0, 0], [0, 0], 1).length, 1);
  assert.equal(s.add(null, [1, 0], 1).length, 0);
  assert.deepEqual(s.add([30, 0, 0], [2, 0], 1).map((d) => d.point), [[30, 0, 0]]);
  assert.deepEqual(s.add([60, 0, 0], [3, 0], 1).map((d) => d.point), [[60, 0, 0]], "a 30 vu jump is over maxGap 5");
  assert.throws(() => new DabSpacer(0), RangeError);
});
