// The sculpting tools of the server, as the palette shows them.
// kind "stroke": a pointer drag is one stroke of dabs (stroke.begin / dabs / end), the brush
// tools of PROTOCOL.md; kind "click": a click applies the tool once where the pointer ray meets
// the surface (tool.apply with a ray), the CSG tools. Global operations are in GLOBAL_OPS.
// `key` is the keyboard shortcut that selects the tool; `short` its name on the compact toolbar
// of small screens.

// `color` ([r, g, b] in 0..1) is the brush cursor's, one per effect: adding green, removing red,
// smoothing blue, sharpening amber, intersecting violet.
const ADD = [0.5, 0.86, 0.5];
const REMOVE = [0.96, 0.48, 0.42];
export const TOOLS = Object.freeze([
  { id: "add_blob", label: "Add blob", short: "Add", key: "a", kind: "stroke", color: ADD },
  { id: "remove_blob", label: "Remove blob", short: "Remove", key: "r", kind: "stroke", color: REMOVE },
  { id: "smooth", label: "Smooth", short: "Smooth", key: "s", kind: "stroke", color: [0.45, 0.74, 0.96] },
  { id: "sharpen", label: "Sharpen", short: "Sharpen", key: "h", kind: "stroke", color: [0.96, 0.78, 0.36] },
  { id: "csg_add", label: "CSG add", short: "∪", key: "c", kind: "click", color: ADD },
  { id: "csg_subtract", label: "CSG subtract", short: "−", key: "x", kind: "click", color: REMOVE },
  { id: "csg_intersect", label: "CSG intersect", short: "∩", key: "i", kind: "click", color: [0.76, 0.56, 0.96] },
]);

export function toolById(id) {
  return TOOLS.find((t) => t.id === id) || TOOLS[0];
}

// The whole-volume operations: morphology (volume.morph, a radius in vu) and global smoothing
// (tool.apply {"tool":"smooth","global":true}, a number of iterations).
export const GLOBAL_OPS = Object.freeze({
  dilate: { amount: "Radius (vu)", min: 0.001, max: 64, step: "any", value: 2, label: "Dilating" },
  erode: { amount: "Radius (vu)", min: 0.001, max: 64, step: "any", value: 2, label: "Eroding" },
  open: { amount: "Radius (vu)", min: 0.001, max: 64, step: "any", value: 2, label: "Opening" },
  close: { amount: "Radius (vu)", min: 0.001, max: 64, step: "any", value: 2, label: "Closing" },
  smooth: { amount: "Iterations", min: 1, max: 100000, step: 1, value: 10, label: "Smoothing" },
});

const INVERSES = { add_blob: "remove_blob", remove_blob: "add_blob", smooth: "sharpen", sharpen: "smooth", csg_add: "csg_subtract", csg_subtract: "csg_add" };

// The tool a modifier turns `id` into: "invert" swaps a tool with its opposite (CSG intersect
// has none and stays), "smooth" is the smoothing brush for strokes; null keeps the tool.
export function toolWithModifier(id, modifier) {
  if (modifier === "invert") return INVERSES[id] || id;
  if (modifier === "smooth" && toolById(id).kind === "stroke") return "smooth";
  return id;
}
