// Keyboard shortcuts, for the whole page except while typing in a field or in a dialog.
//   A R S H C X I: tools (add blob, remove blob, smooth, sharpen, CSG add / subtract /
//   intersect); [ ]: brush radius down / up; { }: strength (blend) down / up;
//   Ctrl+Z: undo; Ctrl+Shift+Z or Ctrl+Y: redo (Cmd on macOS); V: splats / frames view;
//   G: gradient-error shading; 0 or Home: reset view; 1 front, 3 side, 7 top;
//   arrow keys (on the canvas): orbit; + and -: zoom; Escape: cancel the gesture; ?: the
//   shortcuts overlay. KEY_HELP lists them for that overlay. Space and F are held during a
//   drag (ui/gesture-map.js), not pressed.

import { TOOLS } from "./tools.js";

export const KEY_HELP = Object.freeze([
  ...TOOLS.map((t) => [t.key.toUpperCase(), t.label]),
  ["[  ]", "brush radius smaller / larger"],
  ["{  }", "strength (blend) lower / higher"],
  ["Ctrl+Z", "undo"],
  ["Ctrl+Shift+Z, Ctrl+Y", "redo"],
  ["V", "splats / frames view"],
  ["G", "gradient-error shading"],
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
    else if (key === "[") actions.radiusBy(1 / 1.2);
    else if (key === "]") actions.radiusBy(1.2);
    else if (key === "{") actions.strengthBy(-0.05);
    else if (key === "}") actions.strengthBy(0.05);
    else if (key === "v" || key === "V") actions.toggleView();
    else if (key === "g" || key === "G") actions.toggleGradientError();
    else if (key === "0" || key === "Home") actions.camera("home");
    else if (key === "1") actions.camera("front");
    else if (key === "3") actions.camera("side");
    else if (key === "7") actions.camera("top");
    else if (key === "5") actions.toggleOrthographic();
    else if (key === "+" || key === "=") actions.zoom(1 / 1.15);
    else if (key === "-" || key === "_") actions.zoom(1.15);
    else if (key === "Escape") actions.cancel();
    else if (key === "?") actions.help();
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
