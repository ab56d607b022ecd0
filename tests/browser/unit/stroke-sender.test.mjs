// web-client/net/stroke-sender.js: what stroke.begin asks for.
import { test } from "node:test";
import assert from "node:assert/strict";

import { HEIGHT_PER_RADIUS, MAX_HEIGHT, strokeBeginParams } from "../../../web-client/net/stroke-sender.js";

test("add and remove blob strokes stand at strength times half the radius, without build-up", () => {
  assert.deepEqual(strokeBeginParams({ tool: "add_blob", radius: 8, strength: 1, symmetry: [] }), { tool: "add_blob", radius: 8, strength: 1, height: 4 });
  assert.deepEqual(strokeBeginParams({ tool: "remove_blob", radius: 12, strength: 0.25, symmetry: ["x"] }), {
    tool: "remove_blob",
    radius: 12,
    strength: 0.25,
    symmetry: ["x"],
    height: 1.5,
  });
  // monotone in strength and radius
  const h = (radius, strength) => strokeBeginParams({ tool: "add_blob", radius, strength }).height;
  for (const r of [0.5, 3, 8, 14.5, 40])
    for (const s of [0.05, 0.3, 0.55, 0.8]) {
      assert.ok(h(r, s + 0.2) > h(r, s), `r ${r}, strength ${s}`);
      assert.ok(h(r * 1.2, s) >= h(r, s), `r ${r}, strength ${s}`);
    }
});

test("the height never exceeds what the server takes (half the radius) nor the cap", () => {
  assert.equal(HEIGHT_PER_RADIUS, 0.5);
  for (const radius of [0.5, 1, 8.333, 14.4, 17.28, 33.3333, 64, 1024])
    for (const strength of [0.05, 0.35, 1]) {
      const { height } = strokeBeginParams({ tool: "add_blob", radius, strength });
      assert.ok(height > 0 && height <= radius / 2 && height <= MAX_HEIGHT, `radius ${radius}, strength ${strength}: ${height}`);
    }
  assert.equal(strokeBeginParams({ tool: "add_blob", radius: 200, strength: 1 }).height, MAX_HEIGHT);
});

test("build-up strokes and smoothing accumulate and carry no height", () => {
  assert.deepEqual(strokeBeginParams({ tool: "add_blob", radius: 8, strength: 1, buildUp: true }), { tool: "add_blob", radius: 8, strength: 1, accumulate: true });
  for (const tool of ["smooth", "sharpen"])
    for (const buildUp of [false, true])
      assert.deepEqual(strokeBeginParams({ tool, radius: 6, strength: 0.5, buildUp }), { tool, radius: 6, strength: 0.5, accumulate: true });
});
