// web-client/ui/brush-drag.js: F+drag follows the whole drag, so small steps add up.
import { test } from "node:test";
import assert from "node:assert/strict";

import { BrushDrag } from "../../../web-client/ui/brush-drag.js";

test("100 steps of 1 px end where one step of 100 px does: the radius grows by e", () => {
  const drag = new BrushDrag(8, 0.5);
  let brush;
  for (let x = 1; x <= 100; ++x) brush = drag.at(x, 0);
  assert.ok(Math.abs(brush.radius - 8 * Math.E) < 1e-12, `${brush.radius}`);
  assert.deepEqual(drag.at(100, 0), brush);
  assert.equal(brush.second, 0.5);
});

test("up raises the strength by 0.005 a pixel, down lowers it; back to the start restores both", () => {
  const drag = new BrushDrag(12, 0.5);
  assert.ok(Math.abs(drag.at(0, -40).second - 0.7) < 1e-12);
  assert.ok(Math.abs(drag.at(0, 60).second - 0.2) < 1e-12);
  assert.deepEqual(drag.at(0, 0), { radius: 12, second: 0.5 });
});
