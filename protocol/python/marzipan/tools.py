"""Marzipan's sculpting tools and whole-volume operations, as data: generated from protocol/registry/tools.json by protocol/registry/generate.py (docs/tools.md).
Do not edit: change the registry and run `python3 protocol/registry/generate.py write`.

GROUPS: the palette's groups, in order. TOOLS: the local tools in palette order, each a dict
{name (the wire "tool"), label, kind, group, strokes (stroke.begin takes it), dabs, inverse (or
None), description, params, browser}. OPERATIONS: the whole-volume operations ({"op": "morph",
"kind": name} or global smoothing). PARAMETERS: by id, each a dict {id, key (its wire name), type,
in ("op": the operation object, "stroke": stroke.begin), description} with, as the registry gives
them, unit, minimum, exclusive_minimum, maximum, max_per_radius, default (absent: required unless
optional), optional, values, bound, role, only_with, not_with, since; the params of tools and
operations are these same dicts. Lengths in vu.
"""

GROUPS = [
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
    "description": "work the surface in place: smooth, sharpen, flatten or crease it",
  },
  {
    "name": "Shapes",
    "description": "add, cut or keep a primitive shape (CSG)",
  },
]

PARAMETERS = {
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
    "exclusive_minimum": True,
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
    "exclusive_minimum": True,
    "maximum": 64,
    "max_per_radius": 0.5,
    "optional": True,
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
}

TOOLS = [
  {
    "name": "add_blob",
    "label": "Add blob",
    "kind": "surface_speed",
    "group": "Clay",
    "strokes": True,
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
    "strokes": True,
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
    "name": "inflate",
    "label": "Inflate",
    "kind": "surface_speed",
    "group": "Clay",
    "strokes": True,
    "dabs": "swept",
    "inverse": None,
    "description": "moves every point outward along its own normal, strength vu at the centre, less towards the edge of the ROI (add blob without a height); a stroke with a height raises each point by the height along its own normal",
    "params": [
      PARAMETERS["center"],
      PARAMETERS["radius"],
      PARAMETERS["strength"],
      PARAMETERS["height"],
    ],
    "browser": {
      "key": "n",
      "short": "Inflate",
      "icon": "○",
      "color": [0.56, 0.9, 0.72],
    },
  },
  {
    "name": "clay",
    "label": "Clay",
    "kind": "surface_speed",
    "group": "Clay",
    "strokes": True,
    "dabs": "swept",
    "inverse": None,
    "description": "builds up along the stroke's one direction, the average normal of the surface within the radius of its first dab as it began; a stroke with a height raises the surface by the height (without one it is add blob)",
    "params": [
      PARAMETERS["center"],
      PARAMETERS["radius"],
      PARAMETERS["strength"],
      PARAMETERS["height"],
    ],
    "browser": {
      "key": "y",
      "short": "Clay",
      "icon": "▴",
      "color": [0.86, 0.66, 0.48],
    },
  },
  {
    "name": "smooth",
    "label": "Smooth",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": True,
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
    "strokes": True,
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
    "name": "flatten",
    "label": "Flatten",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": True,
    "dabs": "swept",
    "inverse": "contrast",
    "description": "moves the surface towards the plane fitted to the surface within the radius of the stroke's first dab as the stroke began (area-weighted centre and normal), never past it: within 1 vu of the plane strength of its way there at the centre, farther strength vu",
    "params": [PARAMETERS["center"], PARAMETERS["radius"], PARAMETERS["strength"]],
    "browser": {
      "key": "b",
      "short": "Flatten",
      "icon": "▬",
      "color": [0.62, 0.82, 0.9],
    },
  },
  {
    "name": "contrast",
    "label": "Contrast",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": True,
    "dabs": "swept",
    "inverse": "flatten",
    "description": "the same as flatten, away from the plane: bumps rise and hollows sink",
    "params": [PARAMETERS["center"], PARAMETERS["radius"], PARAMETERS["strength"]],
    "browser": {
      "key": "o",
      "short": "Contrast",
      "icon": "≡",
      "color": [0.9, 0.62, 0.82],
    },
  },
  {
    "name": "crease",
    "label": "Crease",
    "kind": "surface_speed",
    "group": "Surface",
    "strokes": True,
    "dabs": "swept",
    "inverse": None,
    "description": "cuts a groove as deep as remove blob's whose window falls to zero at radius / 2.5, so it pinches to a sharp line as it sinks",
    "params": [PARAMETERS["center"], PARAMETERS["radius"], PARAMETERS["strength"]],
    "browser": {
      "key": "w",
      "short": "Crease",
      "icon": "∨",
      "color": [0.8, 0.5, 0.9],
    },
  },
  {
    "name": "csg_add",
    "label": "CSG add",
    "kind": "csg",
    "group": "Shapes",
    "strokes": False,
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
    "strokes": False,
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
    "strokes": False,
    "dabs": "swept",
    "inverse": None,
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
]

OPERATIONS = [
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
]

TOOL_NAMES = tuple(t["name"] for t in TOOLS)


def tool(name: str) -> dict:
    """The tool of that wire name; KeyError for a name that is none."""
    for t in TOOLS:
        if t["name"] == name:
            return t
    raise KeyError(f"no tool {name!r}; the tools are {', '.join(TOOL_NAMES)}")


def stroke_tools() -> tuple:
    """The names stroke.begin takes."""
    return tuple(t["name"] for t in TOOLS if t["strokes"])
