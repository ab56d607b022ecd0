// web-client/ui/gesture-map.js and ui/tools.js: which press starts which gesture, and what a
// modifier makes of the selected tool.
import { test } from "node:test";
import assert from "node:assert/strict";

import { GESTURE_HELP, pressGesture } from "../../../web-client/ui/gesture-map.js";
import { toolWithModifier } from "../../../web-client/ui/tools.js";

const left = (extra = {}) => ({ button: 0, ...extra });

test("a press on the model sculpts; Ctrl inverts, Shift smooths, Alt picks the colour", () => {
  assert.deepEqual(pressGesture(left(), "stroke"), { kind: "stroke", modifier: null });
  assert.deepEqual(pressGesture(left({ ctrl: true }), "stroke"), { kind: "stroke", modifier: "invert" });
  assert.deepEqual(pressGesture(left({ alt: true }), "stroke"), { kind: "pick", modifier: null });
  assert.deepEqual(pressGesture(left({ alt: true }), "click"), { kind: "pick", modifier: null });
  assert.deepEqual(pressGesture(left({ alt: true, ctrl: true }), "stroke"), { kind: "stroke", modifier: "invert" });
  assert.equal(pressGesture(left({ alt: true }), null).kind, "orbit", "beside the model Alt picks nothing");
  assert.deepEqual(pressGesture(left({ shift: true }), "stroke"), { kind: "stroke", modifier: "smooth" });
  assert.deepEqual(pressGesture(left({ ctrl: true }), "click"), { kind: "click", modifier: "invert" });
  assert.deepEqual(pressGesture(left({ shift: true }), "click"), { kind: "click", modifier: null });
});

test("Space, the right and the middle button move the camera even over the model", () => {
  assert.equal(pressGesture(left({ space: true }), "stroke").kind, "orbit");
  assert.equal(pressGesture(left({ space: true, shift: true }), "stroke").kind, "pan");
  assert.equal(pressGesture({ button: 2 }, "stroke").kind, "orbit");
  assert.equal(pressGesture({ button: 2, shift: true }, "stroke").kind, "pan");
  assert.equal(pressGesture({ button: 1 }, "stroke").kind, "pan");
  assert.equal(pressGesture({ button: 3 }, "stroke"), null, "back/forward buttons start nothing");
});

test("beside the model a press orbits (Shift pans); F+drag sizes the brush anywhere", () => {
  assert.equal(pressGesture(left(), null).kind, "orbit");
  assert.equal(pressGesture(left({ shift: true }), null).kind, "pan");
  assert.equal(pressGesture(left({ brushKey: true }), "stroke").kind, "brush");
  assert.equal(pressGesture(left({ brushKey: true }), null).kind, "brush");
});

test("offline, a press on the model does nothing at all (no stroke, no spinning camera)", () => {
  assert.deepEqual(pressGesture(left(), "blocked"), { kind: "none", modifier: null });
  assert.deepEqual(pressGesture(left({ ctrl: true }), "blocked"), { kind: "none", modifier: null });
  assert.equal(pressGesture({ button: 2 }, "blocked").kind, "orbit", "an explicit orbit still turns the camera");
});

test("inverting swaps each tool with its opposite; smoothing replaces brushes only", () => {
  const inv = (id) => toolWithModifier(id, "invert");
  assert.deepEqual(["add_blob", "remove_blob", "smooth", "sharpen", "csg_add", "csg_subtract", "csg_intersect"].map(inv),
    ["remove_blob", "add_blob", "sharpen", "smooth", "csg_subtract", "csg_add", "csg_intersect"]);
  assert.equal(toolWithModifier("sharpen", "smooth"), "smooth");
  assert.equal(toolWithModifier("csg_add", "smooth"), "csg_add");
  assert.equal(toolWithModifier("add_blob", null), "add_blob");
});

test("the overlay's rows name every gesture the map knows", () => {
  const text = GESTURE_HELP.map((r) => r.join(" ")).join("\n");
  for (const words of ["Space + drag", "right drag", "middle drag", "Shift + drag", "Ctrl", "Alt", "F + drag", "wheel", "pinch"])
    assert.ok(text.includes(words), `the overlay mentions ${words}`);
});
