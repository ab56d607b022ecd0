// Keyboard shortcuts, for the whole page except while typing in a field or in a dialog.
//   each tool's key (the tool registry's, ui/tools.js: A add blob, R remove blob, ...) selects
//   it; [ ]: brush radius down / up; { }: strength (blend) down / up;
//   Ctrl+Z: undo; Ctrl+Shift+Z or Ctrl+Y: redo (Cmd on macOS); V: splats / frames view;
//   D: gradient-error shading (the distance field's check; G is grab's); 0 or Home: reset
//   view; 1 front, 3 side, 7 top; arrow keys (on the canvas): orbit; + and -: zoom; Escape: cancel the gesture; ?: the
//   shortcuts overlay. KEY_HELP lists them for that overlay. Space and F are held during a
//   drag (ui/gesture-map.js), not pressed.

import { GROUPS, TOOLS } from "./tools.js";

// The page's own single keys (without Ctrl, Cmd or Alt), by what they do; the tools' keys come
// after them, so a tool's key must be none of PAGE_KEYS (tests/browser/unit/tools.test.mjs).
const KEY_ACTIONS = Object.freeze({
  "[": (a) => a.radiusBy(1 / 1.2),
  "]": (a) => a.radiusBy(1.2),
  "{": (a) => a.strengthBy(-0.05),
  "}": (a) => a.strengthBy(0.05),
  v: (a) => a.toggleView(),
  d: (a) => a.toggleGradientError(),
  0: (a) => a.camera("home"),
  Home: (a) => a.camera("home"),
  1: (a) => a.camera("front"),
  3: (a) => a.camera("side"),
  7: (a) => a.camera("top"),
  5: (a) => a.toggleOrthographic(),
  "+": (a) => a.zoom(1 / 1.15),
  "=": (a) => a.zoom(1 / 1.15),
  "-": (a) => a.zoom(1.15),
  _: (a) => a.zoom(1.15),
  Escape: (a) => a.cancel(),
  "?": (a) => a.help(),
});
// Also taken: F and Space, held during a drag (ui/gesture-map.js).
export const PAGE_KEYS = Object.freeze(new Set([...Object.keys(KEY_ACTIONS).map((k) => k.toLowerCase()), "f", " "]));

// The tools one row per palette group: "G E K T L P", "Warp: Grab, Elastic grab, ...".
export const KEY_HELP = Object.freeze([
  ...GROUPS.map((g) => [g.tools.map((t) => t.key.toUpperCase()).join(" "), `${g.name}: ${g.tools.map((t) => t.label).join(", ")}`]),
  ["[  ]", "brush radius smaller / larger"],
  ["{  }", "strength (blend) lower / higher"],
  ["Ctrl+Z", "undo"],
  ["Ctrl+Shift+Z, Ctrl+Y", "redo"],
  ["V", "splats / frames view"],
  ["D", "gradient-error shading"],
  ["0 or Home", "reset the view to the model"],
  ["1  3  7", "front, side, top (the model's front: the pig's face)"],
  ["5", "orthographic / perspective"],
  ["arrow keys", "orbit (with the model focused)"],
  ["+  −", "zoom"],
  ["Escape", "cancel the gesture"],
  ["?", "this overlay"],
]);

const TYPING = new Set(["text", "url", "number", "search", "email", "password"]);

// Whether keys pressed on `t` are typing into a field (and so no shortcut).
export function isTyping(t) {
  return Boolean(t && (t.tagName === "TEXTAREA" || t.tagName === "SELECT" || (t.tagName === "INPUT" && TYPING.has(t.type))));
}
const ORBIT_STEP_PX = 24;

// The action of a page key; letters in either case (V and v).
function pageAction(key) {
  if (Object.hasOwn(KEY_ACTIONS, key)) return KEY_ACTIONS[key];
  const lower = key.toLowerCase();
  return key.length === 1 && /[a-z]/.test(lower) && Object.hasOwn(KEY_ACTIONS, lower) ? KEY_ACTIONS[lower] : null;
}

export function installShortcuts(doc, actions) {
  doc.addEventListener("keydown", (e) => {
    const t = e.target;
    if (doc.querySelector("dialog[open]")) return;
    if (isTyping(t)) return;
    const mod = e.ctrlKey || e.metaKey;
    const key = e.key;
    let handled = true;
    if (mod && (key === "z" || key === "Z")) {
      if (e.shiftKey) actions.redo();
      else actions.undo();
    } else if (mod && (key === "y" || key === "Y")) actions.redo();
    else if (mod || e.altKey) handled = false;
    else if (pageAction(key)) pageAction(key)(actions);
    else if (t === actions.canvas && key.startsWith("Arrow")) {
      const dx = key === "ArrowLeft" ? -ORBIT_STEP_PX : key === "ArrowRight" ? ORBIT_STEP_PX : 0;
      const dy = key === "ArrowUp" ? -ORBIT_STEP_PX : key === "ArrowDown" ? ORBIT_STEP_PX : 0;
      actions.orbit(dx, dy);
    } else {
      const tool = TOOLS.find((x) => x.key === key.toLowerCase());
      if (tool && !(t && t.tagName === "INPUT" && t.type === "range" && key.length !== 1)) actions.tool(tool.id);
      else handled = false;
    }
    if (handled) e.preventDefault();
  });
}
