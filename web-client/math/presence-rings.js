// What this page draws of the others (PROTOCOL.md "Presence"): each other sculptor's brush
// ring on the model in their colour (a painting sculptor's in their paint colour, the brush's
// `color`) with their name beside it, and a brief mark, in the author's colour, of the region
// another client's edit just changed.
// Conventions: world in vu, y up; screen positions in CSS pixels of the canvas, y down from its
// top-left corner; colours "#rrggbb" on the wire, [r, g, b] in 0..1 here; times in ms of the
// caller's clock; a brush's paint colour [r, g, b] in 0..255 on the wire. Rings are
// render/brush-cursor.js's ring objects. Pure: no DOM, no GL.

import { transformPoint } from "./mat4.js";
import { addScaled, dot, sub } from "./vec3.js";

// How long an edit's region stays marked, fading out (ms).
export const EDIT_MARK_MS = 1500;
const RING_LINE_PIXELS = 2;
const LABEL_GAP_PX = 4;

// A brush's paint colour, [r, g, b] of integers in 0..255, as [r, g, b] in 0..1; null for
// anything else.
export function paintColor(value) {
  const ok = Array.isArray(value) && value.length === 3 && value.every((c) => Number.isInteger(c) && c >= 0 && c <= 255);
  return ok ? value.map((c) => c / 255) : null;
}

// "#rrggbb" as [r, g, b] in 0..1; null for anything else.
export function hexColor(text) {
  const m = typeof text === "string" && /^#([0-9a-fA-F]{2})([0-9a-fA-F]{2})([0-9a-fA-F]{2})$/.exec(text);
  return m ? [1, 2, 3].map((i) => parseInt(m[i], 16) / 255) : null;
}

// Where the world point p shows in a width x height canvas seen through `viewProjection`:
// {x, y, visible}; not visible behind the eye or outside the view.
export function project(viewProjection, p, width, height) {
  const m = viewProjection;
  const w = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
  const [nx, ny, nz] = transformPoint(m, p);
  return {
    x: ((nx + 1) / 2) * width,
    y: ((1 - ny) / 2) * height,
    visible: w > 0 && Math.abs(nx) <= 1 && Math.abs(ny) <= 1 && Math.abs(nz) <= 1,
  };
}

// The rings and name labels of the others. `others`: [{client, name, color, brush?, seenAt}]
// (the newest presence of each, seenAt when it arrived); `camera`: an OrbitCamera updated for
// the canvas (its eye, up, fovY, viewProjection); width, height: the canvas in CSS pixels;
// `staleMs`: a brush not confirmed for this long is no longer shown.
// Each ring's line is about RING_LINE_PIXELS wide on screen at its depth; a ring whose surface
// faces away from the eye (seen through the model, since rings are drawn over everything) is
// fainter; a sculpting client's ring is brighter, thicker and has a dot at its centre.
// Labels: {client, name, tool, color, x, y, visible, active}, (x, y) just above the ring's top.
export function presenceRings(others, camera, width, height, now, staleMs) {
  const rings = [];
  const labels = [];
  const eye = camera.eye;
  const up = camera.up;
  const perPixelAtUnit = (2 * Math.tan(camera.fovY / 2)) / Math.max(1, height);
  for (const o of others) {
    const b = o.brush;
    const own = hexColor(o.color);
    if (!b || !own || now - o.seenAt > staleMs) continue;
    const color = paintColor(b.color) || own;
    const toEye = sub(eye, b.point);
    const depth = Math.max(1e-6, Math.sqrt(dot(toEye, toEye)));
    const facing = dot(toEye, b.normal) >= 0;
    const width1 = RING_LINE_PIXELS * perPixelAtUnit * depth;
    rings.push({
      center: b.point,
      normal: b.normal,
      radius: b.radius,
      width: b.active ? 1.5 * width1 : width1,
      color,
      alpha: (b.active ? 0.95 : 0.7) * (facing ? 1 : 0.4),
      primary: b.active,
      client: o.client,
    });
    const top = project(camera.viewProjection, addScaled(b.point, up, b.radius), width, height);
    labels.push({ client: o.client, name: o.name, tool: b.tool, color: o.color, x: top.x, y: top.y - LABEL_GAP_PX, visible: top.visible, active: b.active });
  }
  return { rings, labels };
}

// The twelve edges of the box of voxel centres of a half-open voxel box {lo, hi}.
export function boxEdges({ lo, hi }) {
  const top = hi.map((v) => v - 1);
  const corner = (i) => [i & 1 ? top[0] : lo[0], i & 2 ? top[1] : lo[1], i & 4 ? top[2] : lo[2]];
  const edges = [];
  for (let i = 0; i < 8; ++i) for (const bit of [1, 2, 4]) if (!(i & bit)) edges.push([corner(i), corner(i | bit)]);
  return edges;
}

// The regions others' edits changed lately. add() a region (a session.changed roi) with its
// author's colour; marks(now) the ones still shown, each {client, segments, color, alpha}, the
// alpha falling from 0.9 to 0 over EDIT_MARK_MS. A newer edit of the same client replaces its
// mark (a stroke's messages mark where it is now, not its whole trail).
export class EditMarks {
  #marks = new Map(); // client -> {roi, color, at}

  add(client, roi, color, at) {
    const rgb = hexColor(color);
    if (!rgb || !roi || !Array.isArray(roi.lo) || !Array.isArray(roi.hi)) return false;
    this.#marks.set(client, { roi, color: rgb, at });
    return true;
  }

  marks(now) {
    const out = [];
    for (const [client, m] of this.#marks) {
      const age = now - m.at;
      if (age >= EDIT_MARK_MS || age < 0) {
        if (age >= EDIT_MARK_MS) this.#marks.delete(client);
        continue;
      }
      out.push({ client, segments: boxEdges(m.roi), color: m.color, alpha: 0.9 * (1 - age / EDIT_MARK_MS) });
    }
    return out;
  }

  get size() {
    return this.#marks.size;
  }

  clear() {
    this.#marks.clear();
  }
}
