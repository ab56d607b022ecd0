// web-client/math/lazy-mouse.js: the stroke stabiliser.
import { test } from "node:test";
import assert from "node:assert/strict";

import { LazyMouse } from "../../../web-client/math/lazy-mouse.js";

test("the brush stays put while the pointer moves within the slack, then trails it by the slack", () => {
  const lazy = new LazyMouse(20);
  assert.deepEqual(lazy.follow(100, 100), [100, 100], "the first point places the brush");
  assert.equal(lazy.follow(110, 100), null);
  assert.equal(lazy.follow(100, 119), null);
  assert.deepEqual(lazy.follow(150, 100), [130, 100]);
  const [x, y] = lazy.follow(150, 160);
  assert.ok(Math.abs(Math.hypot(150 - x, 160 - y) - 20) < 1e-9, "pulled tight: exactly the slack behind");
});

test("a jittering pointer along a line gives a brush path with far less sideways wobble", () => {
  const lazy = new LazyMouse(15);
  let wobble = 0, raw = 0;
  for (let i = 0; i <= 200; ++i) {
    const jitter = (i % 2 ? 1 : -1) * 6;
    raw = Math.max(raw, Math.abs(jitter));
    const at = lazy.follow(3 * i, 100 + jitter);
    if (at && i > 20) wobble = Math.max(wobble, Math.abs(at[1] - 100));
  }
  assert.equal(raw, 6);
  assert.ok(wobble < 1.5, `wobble ${wobble}`);
});

test("a slack of 0 is off: the brush is the pointer", () => {
  const lazy = new LazyMouse(0);
  assert.deepEqual(lazy.follow(1, 2), [1, 2]);
  assert.deepEqual(lazy.follow(1.5, 2), [1.5, 2]);
});
