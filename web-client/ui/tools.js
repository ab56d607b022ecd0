// The sculpting tools as the palette shows them, read from the tool registry
// (protocol/registry/tools.json, generated into protocol/js/tools.js; docs/tools.md): nothing
// about a tool is written here, so a tool the registry gains appears in the palette, its group,
// the shortcuts and the overlay by itself.
// Each entry: `id` (the wire name), `label`, `short` (its name on the compact toolbar of small
// screens), `key` (the shortcut that selects it), `icon`, `color` ([r, g, b] in 0..1, the brush
// cursor's: one per effect), `group`, `inverse` (or null), `takes` (the set of its parameters'
// wire keys) and `kind`, the gesture: "stroke" for a tool that strokes (a drag is one stroke of
// dabs: stroke.begin / dabs / end), "click" for one that does not (a click applies it once where
// the pointer ray meets the surface: tool.apply with a ray, the CSG tools); `warp`, for a tool of
// the registry's kind "warp", what its dabs are ("anchored": grab, twist ...; "path": snake
// hook; math/warp-drag.js; "surface_path": pinch path, picked on the surface as a brush's,
// ui/sculpt.js), else null; `paint`, true for a tool of the registry's kind "paint"
// (paint and mask: they change colour or mask, never the clay); `radiusRange`, [min, max] of
// its radius in vu (null for a tool without one). Global operations are in GLOBAL_OPS, the
// whole-volume mask methods in MASK_OPS.
// The registry is imported by a relative path, not "/protocol/js/...": the server serves this
// file at /ui/tools.js and protocol/js/ at /protocol/js/, so the browser resolves it to the same
// module as the other imports, and node's unit tests find it on disk.

import { GROUPS as REGISTRY_GROUPS, OPERATIONS, TOOLS as REGISTRY_TOOLS } from "../../protocol/js/tools.js";

const rangeOf = (p) => (p && p.type === "number" ? Object.freeze([p.minimum, p.maximum]) : null);

export const TOOLS = Object.freeze(
  REGISTRY_TOOLS.map((t) =>
    Object.freeze({
      id: t.name,
      label: t.label,
      short: t.browser.short,
      key: t.browser.key,
      icon: t.browser.icon,
      color: t.browser.color,
      group: t.group,
      inverse: t.inverse,
      takes: new Set(t.params.map((p) => p.key)),
      kind: t.strokes ? "stroke" : "click",
      warp: t.kind === "warp" ? t.dabs : null,
      paint: t.kind === "paint",
      radiusRange: rangeOf(t.params.find((p) => p.key === "radius")),
    }),
  ),
);

// The palette's groups in order, each {name, description, tools}, without the groups that have
// no tool yet.
export const GROUPS = Object.freeze(
  REGISTRY_GROUPS.map((g) => Object.freeze({ ...g, tools: TOOLS.filter((t) => t.group === g.name) })).filter((g) => g.tools.length),
);

export function toolById(id) {
  return TOOLS.find((t) => t.id === id) || TOOLS[0];
}

// A tool's name inside a sentence ("sculpting with add blob", "CSG add"): its label, lower-cased
// unless it starts with an abbreviation.
export function toolName(id) {
  const t = TOOLS.find((x) => x.id === id);
  if (!t) return String(id).replace(/_/g, " ");
  const first = t.label.split(" ")[0];
  return first === first.toUpperCase() ? t.label : t.label[0].toLowerCase() + t.label.slice(1);
}

// The whole-volume operations by name, each {menu, amount, min, max, step, value, label}: the
// menu entry, the amount's name and range (its first parameter: morphology's radius in vu, global
// smoothing's iterations), the amount the menu starts with, and what the page says while it runs
// ("Dilating the whole volume").
export const GLOBAL_OPS = Object.freeze(
  Object.fromEntries(
    OPERATIONS.map((o) => {
      const p = o.params[0];
      const name = p.key[0].toUpperCase() + p.key.slice(1);
      return [
        o.name,
        Object.freeze({
          menu: o.label,
          amount: p.unit ? `${name} (${p.unit})` : name,
          min: p.minimum,
          max: p.maximum,
          step: p.type === "integer" ? 1 : "any",
          value: o.browser.value,
          label: o.browser.doing,
        }),
      ];
    }),
  ),
);

// The whole-volume mask operations (PROTOCOL.md: RPC methods with params {}), by method, each
// {menu, label} as GLOBAL_OPS has them; they take no amount.
export const MASK_OPS = Object.freeze({
  "mask.clear": Object.freeze({ menu: "Clear the mask", label: "Clearing the mask of" }),
  "mask.invert": Object.freeze({ menu: "Invert the mask", label: "Inverting the mask of" }),
  "mask.fill": Object.freeze({ menu: "Mask everything", label: "Masking" }),
});

// The tool a modifier turns `id` into: "invert" swaps a tool with its opposite (one without, like
// CSG intersect, stays), "smooth" is the smoothing brush for strokes; null keeps the tool.
export function toolWithModifier(id, modifier) {
  if (modifier === "invert") return TOOLS.find((t) => t.id === id)?.inverse || id;
  if (modifier === "smooth" && toolById(id).kind === "stroke") return "smooth";
  return id;
}
