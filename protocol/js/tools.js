// Marzipan's sculpting tools and whole-volume operations, as data: generated from protocol/registry/tools.json by protocol/registry/generate.py (docs/tools.md).
// Do not edit: change the registry and run `python3 protocol/registry/generate.py write`.
//
// GROUPS: the palette's groups, in order. TOOLS: the local tools in palette order, each {name (the
// wire "tool"), label, kind, group, strokes (stroke.begin takes it), dabs, inverse (or null),
// description, params, browser: {key, short, icon, color}}. OPERATIONS: the whole-volume
// operations ({"op":"morph","kind":name} or global smoothing), each {name, label, kind,
// description, params, browser: {doing, value}}. PARAMETERS: by id, each {id, key (its wire
// name), type, in ("op": the operation object, "stroke": stroke.begin), description} with, as the
// registry gives them, unit, minimum, exclusive_minimum, maximum, max_per_radius, default (absent:
// required unless optional), optional, values, bound, role, only_with, not_with, since; the
// params of tools and operations are these same objects. Lengths in vu. Everything is frozen.

function frozen(value) {
  if (value && typeof value === "object") {
    for (const v of Object.values(value)) frozen(v);
    Object.freeze(value);
  }
  return value;
}

export const GROUPS = frozen([
  {
    "name": "Clay",
    "description": "build material up or carve it away",
  },
  {
    "name": "Warp",
    "description": "move the material that is there",
  },
  {
    "name": "Surface",
    "description": "work the surface in place: smooth or sharpen it",
  },
  {
    "name": "Shapes",
    "description": "add, cut or keep a primitive shape (CSG)",
  },
]);

export const PARAMETERS = frozen({
  "center": {
    "id": "center",
    "key": "center",
    "type": "point",
    "role": "center",
    "unit": "vu",
    "bound": 1000000,
    "in": ["op"],
    "description": "where the tool acts; the tool's region must meet the domain (tool.apply may give a pick ray instead)",
  },
  "radius": {
    "id": "radius",
    "key": "radius",
    "type": "number",
    "unit": "vu",
    "minimum": 0.5,
    "maximum": 1024,
    "default": 8,
    "in": ["op", "stroke"],
    "description": "half side of the cubic region of interest (ROI) around the centre",
  },
  "strength": {
    "id": "strength",
    "key": "strength",
    "type": "number",
    "minimum": 0,
    "exclusive_minimum": true,
    "maximum": 1,
    "default": 1,
    "in": ["op", "stroke"],
    "description": "how far one application moves the surface (see each tool)",
  },
  "height": {
    "id": "height",
    "key": "height",
    "type": "number",
    "unit": "vu",
    "minimum": 0,
    "exclusive_minimum": true,
    "maximum": 64,
    "max_per_radius": 0.5,
    "optional": true,
    "in": ["stroke"],
    "not_with": ["accumulate"],
    "since": "1.4",
    "description": "the stroke moves the surface under a dab's centre by this much, however often it passes",
  },
  "shape": {
    "id": "shape",
    "key": "shape",
    "type": "enum",
    "values": ["sphere", "box", "cylinder"],
    "in": ["op"],
    "description": "the primitive",
  },
  "shape_radius": {
    "id": "shape_radius",
    "key": "radius",
    "type": "number",
    "unit": "vu",
    "minimum": 0.5,
    "maximum": 1024,
    "in": ["op"],
    "description": "sphere radius; box half side; cylinder radius and half height",
  },
  "blend": {
    "id": "blend",
    "key": "blend",
    "type": "number",
    "unit": "vu",
    "minimum": 0,
    "maximum": 1024,
    "max_per_radius": 1,
    "default": 0,
    "in": ["op"],
    "description": "smooth-blend radius, 0 = sharp crease",
  },
  "axis": {
    "id": "axis",
    "key": "axis",
    "type": "enum",
    "values": ["x", "y", "z"],
    "default": "y",
    "only_with": {
      "shape": ["cylinder"],
    },
    "in": ["op"],
    "description": "the cylinder's axis",
  },
  "iterations": {
    "id": "iterations",
    "key": "iterations",
    "type": "integer",
    "minimum": 1,
    "maximum": 100000,
    "in": ["op"],
    "description": "whole-volume steps",
  },
  "morph_radius": {
    "id": "morph_radius",
    "key": "radius",
    "type": "number",
    "unit": "vu",
    "minimum": 0.001,
    "maximum": 64,
    "in": ["op"],
    "description": "radius of the spherical structuring element",
  },
});

export const TOOLS = frozen([
  {
    "name": "add_blob",
    "label": "Add blob",
    "kind": "surface_speed",
    "group": "Clay",
    "strokes": true,
    "dabs": "swept",
    "inverse": "remove_blob",
    "description": "moves the surface outward by strength vu at the centre, less towards the edge of the ROI, nothing outside it; a stroke with a height raises it by the height",
    "params": [
      PARAMETERS["center"],
      PARAMETERS["radius"],
      PARAMETERS["strength"],
      PARAMETERS["height"],
    ],
    "browser": {
      "key": "a",
      "short": "Add",
      "icon": "+",
      "color": [0.5, 0.86, 0.5],
    },
  },
  {
    "name": "remove_blob",
    "label": "Remove blob",
    "kind": "surface_speed",
    "group": "Clay",
    "strokes": true,
    "dabs": "swept",
    "inverse": "add_blob",
    "description": "the same as add_blob, inward",
    "params": [
      PARAMETERS["center"],
      PARAMETERS["radius"],
      PARAMETERS["strength"],
      PARAMETERS["height"],
    ],
    "browser": {
      "key": "r",
      "short": "Remove",
      "icon": "−",
      "color": [0.96, 0.48, 0.42],
    },
  },
  {
    "name": "smooth",
    "label": "Smooth",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": true,
    "dabs": "swept",
    "inverse": "sharpen",
    "description": "32 steps of localized mean curvature flow, dt = strength / 6 each",
    "params": [PARAMETERS["center"], PARAMETERS["radius"], PARAMETERS["strength"]],
    "browser": {
      "key": "s",
      "short": "Smooth",
      "icon": "≈",
      "color": [0.45, 0.74, 0.96],
    },
  },
  {
    "name": "sharpen",
    "label": "Sharpen",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": true,
    "dabs": "swept",
    "inverse": "smooth",
    "description": "the smoothing step backwards in time, curvature limited to 1/vu",
    "params": [PARAMETERS["center"], PARAMETERS["radius"], PARAMETERS["strength"]],
    "browser": {
      "key": "h",
      "short": "Sharpen",
      "icon": "∧",
      "color": [0.96, 0.78, 0.36],
    },
  },
  {
    "name": "csg_add",
    "label": "CSG add",
    "kind": "csg",
    "group": "Shapes",
    "strokes": false,
    "dabs": "swept",
    "inverse": "csg_subtract",
    "description": "union with the shape: min(d, t)",
    "params": [
      PARAMETERS["shape"],
      PARAMETERS["center"],
      PARAMETERS["shape_radius"],
      PARAMETERS["blend"],
      PARAMETERS["axis"],
    ],
    "browser": {
      "key": "c",
      "short": "∪",
      "icon": "∪",
      "color": [0.5, 0.86, 0.5],
    },
  },
  {
    "name": "csg_subtract",
    "label": "CSG subtract",
    "kind": "csg",
    "group": "Shapes",
    "strokes": false,
    "dabs": "swept",
    "inverse": "csg_add",
    "description": "removes the shape: max(d, -t)",
    "params": [
      PARAMETERS["shape"],
      PARAMETERS["center"],
      PARAMETERS["shape_radius"],
      PARAMETERS["blend"],
      PARAMETERS["axis"],
    ],
    "browser": {
      "key": "x",
      "short": "−",
      "icon": "∖",
      "color": [0.96, 0.48, 0.42],
    },
  },
  {
    "name": "csg_intersect",
    "label": "CSG intersect",
    "kind": "csg",
    "group": "Shapes",
    "strokes": false,
    "dabs": "swept",
    "inverse": null,
    "description": "keeps only what is inside the shape: max(d, t)",
    "params": [
      PARAMETERS["shape"],
      PARAMETERS["center"],
      PARAMETERS["shape_radius"],
      PARAMETERS["blend"],
      PARAMETERS["axis"],
    ],
    "browser": {
      "key": "i",
      "short": "∩",
      "icon": "∩",
      "color": [0.76, 0.56, 0.96],
    },
  },
]);

export const OPERATIONS = frozen([
  {
    "name": "dilate",
    "label": "dilate (grow)",
    "kind": "morphology",
    "description": "grows the solid by radius vu (a sphere of radius R becomes R + radius)",
    "params": [PARAMETERS["morph_radius"]],
    "browser": {
      "doing": "Dilating",
      "value": 2,
    },
  },
  {
    "name": "erode",
    "label": "erode (shrink)",
    "kind": "morphology",
    "description": "shrinks the solid by radius vu",
    "params": [PARAMETERS["morph_radius"]],
    "browser": {
      "doing": "Eroding",
      "value": 2,
    },
  },
  {
    "name": "open",
    "label": "open (remove thin parts)",
    "kind": "morphology",
    "description": "erode then dilate: removes parts thinner than 2 radius",
    "params": [PARAMETERS["morph_radius"]],
    "browser": {
      "doing": "Opening",
      "value": 2,
    },
  },
  {
    "name": "close",
    "label": "close (fill gaps)",
    "kind": "morphology",
    "description": "dilate then erode: fills gaps narrower than 2 radius",
    "params": [PARAMETERS["morph_radius"]],
    "browser": {
      "doing": "Closing",
      "value": 2,
    },
  },
  {
    "name": "smooth",
    "label": "smooth (curvature flow)",
    "kind": "surface_speed",
    "description": "iterations steps of mean curvature flow over the whole volume, dt = strength / 6 each",
    "params": [PARAMETERS["iterations"], PARAMETERS["strength"]],
    "browser": {
      "doing": "Smoothing",
      "value": 10,
    },
  },
]);

export const TOOL_NAMES = frozen(TOOLS.map((t) => t.name));
