// What the brush cursor draws for a tool at a surface point, as plain geometry: rings (circles
// given by centre, normal and radius) and straight segments. Brushes get the ring of their
// radius in the surface's tangent plane and an inner ring at radius × strength (the strongest
// part of the window, and how strong); CSG tools get a ghost of the shape they apply, centred
// on the point as the server centres it (PROTOCOL.md: sphere radius, box half side, cylinder
// radius and half height, axis-aligned). During a warp stroke (warpGhost) the cursor shows
// what the drag does: an arrow from the anchor to the pointer's point for grab, elastic grab
// and snake hook (the snake's whole path; elastic grab also the ring of 3 radii it reaches), the
// turned arc for twist, the ring scaled for scale and pinch; flatten and contrast show the plane they work towards as a disc (planeGhost).
// Conventions: vu, world axes; a ring's normal is unit; a ring with a `width` is drawn that
// wide (a disc: radius r/2, width r), the others get the cursor's line width.

import { addScaled, cross, dot, length, normalize, scale, sub } from "./vec3.js";
import { warpAmount } from "./warp-drag.js";

const AXES = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
const ARROW_HEAD = Math.PI / 7; // half the angle of an arrow's head
const ARC_STEP = Math.PI / 48; // the chord of a drawn arc
export const TWIST_ARC = 0.75; // the twist's arc runs at this fraction of the radius
export const PLANE_ALPHA = 0.22; // the plane disc's opacity (its rim is drawn as a ring)
export const ELASTIC_REACH = 3; // elastic grab changes the ball of this many radii about the anchor

// kind: "stroke" or "click"; shape: sphere|box|cylinder (click tools); axis: 0, 1, 2 (cylinder).
// Returns {rings: [{center, normal, radius, inner}], segments: [[a, b]]}.
export function brushGhost({ kind, shape = "sphere", axis = 1, strength = 1 }, center, normal, radius) {
  if (kind === "stroke") {
    const rings = [{ center, normal, radius, inner: false }];
    if (strength < 1) rings.push({ center, normal, radius: radius * strength, inner: true });
    return { rings, segments: [] };
  }
  if (shape === "sphere") return { rings: AXES.map((n) => ({ center, normal: n, radius, inner: false })), segments: [] };
  if (shape === "cylinder") {
    const a = AXES[axis];
    const end = (s) => center.map((c, i) => c + s * radius * a[i]);
    const rings = [-1, 1].map((s) => ({ center: end(s), normal: a, radius, inner: false }));
    const [u, v] = AXES.filter((_, i) => i !== axis);
    const segments = [];
    for (const [d, sign] of [[u, 1], [u, -1], [v, 1], [v, -1]]) {
      const off = d.map((x) => x * sign * radius);
      segments.push([end(-1).map((c, i) => c + off[i]), end(1).map((c, i) => c + off[i])]);
    }
    return { rings, segments };
  }
  // box: its 12 edges
  const corner = (sx, sy, sz) => [center[0] + sx * radius, center[1] + sy * radius, center[2] + sz * radius];
  const segments = [];
  for (const a of [-1, 1])
    for (const b of [-1, 1]) {
      segments.push([corner(-1, a, b), corner(1, a, b)]);
      segments.push([corner(a, -1, b), corner(a, 1, b)]);
      segments.push([corner(a, b, -1), corner(a, b, 1)]);
    }
  return { rings: [], segments };
}

// The segments of an arrow from a to b, its head in the plane with normal `viewNormal` (facing
// the camera, so the head shows open), the head's sides `head` vu long (at most half the
// arrow). Nothing for an arrow shorter than 1e-6 vu.
export function arrowSegments(a, b, viewNormal, head) {
  const d = sub(b, a);
  const len = length(d);
  if (len < 1e-6) return [];
  const u = scale(d, 1 / len);
  const side = normalize(cross(viewNormal, u));
  const h = Math.min(head, len / 2);
  const back = addScaled(b, u, -h * Math.cos(ARROW_HEAD));
  return [[a, b], [b, addScaled(back, side, h * Math.sin(ARROW_HEAD))], [b, addScaled(back, side, -h * Math.sin(ARROW_HEAD))]];
}

// A unit vector in the plane with unit normal n, along v's part in it (or any, for v along n).
function inPlane(v, n) {
  const t = sub(v, scale(n, dot(v, n)));
  if (length(t) > 1e-6) return normalize(t);
  return normalize(cross(Math.abs(n[1]) < 0.9 ? [0, 1, 0] : [1, 0, 0], n));
}

// The segments of the arc of the circle about `center` with unit normal n and radius r, from
// the direction `from` (in the plane) turned by `angle` (right-handed about n).
export function arcSegments(center, n, r, from, angle) {
  const e1 = inPlane(from, n);
  const e2 = cross(n, e1);
  const steps = Math.max(1, Math.ceil(Math.abs(angle) / ARC_STEP));
  const at = (a) => addScaled(addScaled(center, e1, r * Math.cos(a)), e2, r * Math.sin(a));
  const segments = [];
  for (let i = 0; i < steps; ++i) segments.push([at((angle * i) / steps), at((angle * (i + 1)) / steps)]);
  return segments;
}

// The cursor of an open warp stroke: `name` the tool's wire name, `dabs` its registry dabs
// ("anchored" | "path" | "surface_path": its ring alone); anchor, anchorNormal: the picked surface point and its normal; point:
// the pointer's point on the plane through the anchor facing the camera (null before it
// moved); path: a path tool's points so far, anchor first; direction: twist, scale and pinch's
// stroke.begin direction; viewNormal: the camera's backward axis. The ring of the radius stays
// at the anchor; what the drag does is drawn from there.
// Returns {rings: [{center, normal, radius, inner}], segments}.
export function warpGhost({ name, dabs }, { anchor, anchorNormal, point, path = [], direction = null, viewNormal }, radius) {
  const rings = [{ center: anchor, normal: anchorNormal, radius, inner: false }];
  // elastic grab's radius is the Kelvinlet's scale; what it changes reaches 3 radii (registry)
  if (name === "elastic_grab") rings.push({ center: anchor, normal: anchorNormal, radius: ELASTIC_REACH * radius, inner: true });
  const segments = [];
  if (!point) return { rings, segments };
  const head = 0.3 * radius;
  const s = warpAmount(anchor, point, direction, radius);
  if (name === "twist") {
    // angle = s pi/2 about the anchor's outward normal, drawn from the drag's direction
    const from = direction || sub(point, anchor);
    const arc = arcSegments(anchor, anchorNormal, TWIST_ARC * radius, from, (s * Math.PI) / 2);
    segments.push(...arc);
    if (arc.length && s !== 0) {
      // the head on the arc's end, along its last chord, half a grab arrow's (its shaft not drawn)
      const [a, b] = arc[arc.length - 1];
      segments.push(...arrowSegments(addScaled(b, normalize(sub(b, a)), -head), b, anchorNormal, head / 2).slice(1));
    }
  } else if (name === "scale") {
    rings.push({ center: anchor, normal: anchorNormal, radius: radius * scaleFactor(s), inner: true });
  } else if (name === "pinch") {
    rings.push({ center: anchor, normal: anchorNormal, radius: radius * pinchFactor(s), inner: true });
  } else {
    // grab and elastic grab: the anchor goes to the point; snake hook: it went along the path
    let line = [anchor, point];
    if (dabs === "path" && path.length > 1) line = length(sub(point, path[path.length - 1])) > 1e-6 ? [...path, point] : path;
    for (let i = 0; i + 2 < line.length; ++i) segments.push([line[i], line[i + 1]]);
    segments.push(...arrowSegments(line[line.length - 2], line[line.length - 1], viewNormal, head));
    rings.push({ center: point, normal: anchorNormal, radius, inner: true });
  }
  return { rings, segments };
}

// Scale's factor for a drag of s radii: 2^s, within 0.25 to 4 (the server's bounds, registry).
export function scaleFactor(s) {
  return Math.min(4, Math.max(0.25, 2 ** s));
}

// Pinch's factor towards the anchor's normal line for a drag of s radii: e^-a, a = s / 2 within
// -1 to 1 (the registry's description of pinch).
export function pinchFactor(s) {
  return Math.exp(-Math.min(1, Math.max(-1, s / 2)));
}

// The plane a flatten or contrast stroke works towards ({point, normal}, the server's), as a
// translucent disc of the brush radius about the plane's point and its rim.
export function planeGhost(plane, radius) {
  const normal = normalize(plane.normal);
  return {
    rings: [
      { center: plane.point, normal, radius: radius / 2, width: radius, inner: true, alpha: PLANE_ALPHA },
      { center: plane.point, normal, radius, inner: false },
    ],
    segments: [],
  };
}
