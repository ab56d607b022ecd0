// The one map from a press (button, modifier keys, where it landed) to a gesture, shared by
// the pointer handling and the shortcuts overlay, so what the overlay says is what happens.
// A press on the model with the primary button sculpts with the selected tool; Ctrl or Cmd
// inverts the tool (add <-> remove, smooth <-> sharpen, CSG add <-> subtract, mask <-> unmask)
// and Shift smooths, whatever tool is selected, as in other sculpting programs; Alt picks the
// colour under the pointer into the paint colour. Camera moves have
// buttons or keys of their own that work anywhere, so a model that fills the view can still
// be turned: Space+drag or right drag orbits, middle drag, Shift+right drag or Shift+Space+drag
// pans. Holding F while dragging changes the brush (sideways: radius, up and down: strength).
// A press beside the model orbits (Shift: pans).

// One row per gesture for the shortcuts overlay: [what, how with a mouse, how on touch].
export const GESTURE_HELP = Object.freeze([
  ["sculpt with the selected tool", "drag on the model", "one finger on the model"],
  ["invert the tool (add ↔ remove, smooth ↔ sharpen, flatten ↔ contrast, mask ↔ unmask)", "Ctrl or Cmd + drag on the model", ""],
  ["pick the colour under the pointer as the paint colour", "Alt + click on the model", ""],
  ["warp (grab, twist …): the anchor goes where the pointer points", "drag from the model", "one finger from the model"],
  ["smooth, whatever the tool", "Shift + drag on the model", ""],
  ["orbit", "Space + drag, right drag, or drag beside the model", "one finger beside the model, or two fingers turning"],
  ["pan", "middle drag, Shift + right drag, or Shift + Space + drag", "two fingers moved together"],
  ["zoom towards the pointer", "wheel", "pinch"],
  ["brush radius and strength", "F + drag (sideways: radius, up and down: strength)", ""],
]);

// press: {button, ctrl, alt, shift, space, brushKey} (booleans but button, the DOM's number);
// sculptKind: what a press at this point would sculpt: "stroke" or "click" (on the model, with
// edit rights), "blocked" (on the model while the session cannot be edited: nothing happens),
// or null (beside the model).
// Returns {kind, modifier} with kind one of "stroke", "click", "pick", "orbit", "pan", "brush",
// "none" and modifier null, "invert" or "smooth" (for stroke and click), or null for a press
// that starts nothing.
export function pressGesture({ button, ctrl = false, alt = false, shift = false, space = false, brushKey = false }, sculptKind) {
  const camera = (kind) => ({ kind, modifier: null });
  if (button === 1) return camera("pan");
  if (button === 2) return camera(shift ? "pan" : "orbit");
  if (button !== 0) return null;
  if (space) return camera(shift ? "pan" : "orbit");
  if (brushKey) return camera("brush");
  if (sculptKind === "blocked") return camera("none");
  if (sculptKind === "stroke" || sculptKind === "click") {
    if (alt && !ctrl) return camera("pick");
    const modifier = ctrl ? "invert" : shift && sculptKind === "stroke" ? "smooth" : null;
    return { kind: sculptKind, modifier };
  }
  return camera(shift ? "pan" : "orbit");
}
