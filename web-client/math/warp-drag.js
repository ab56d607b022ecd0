// Warp strokes (the registry's tools of kind "warp": grab, elastic grab, snake hook, twist,
// scale, pinch; PROTOCOL.md, stroke.begin): what a drag sends. The press picks the anchor on
// the surface, the stroke's first dab; every later pointer position becomes the point where the
// pointer's ray meets the plane through the anchor that faces the camera, so the anchor goes
// exactly where the pointer points ("grab must feel direct"), at the anchor's depth.
// The registry's `dabs` says what the points mean to the server: "anchored" (grab, elastic
// grab, twist, scale, pinch: only the stroke's last point counts, so a drag needs only the
// newest; net/stroke-sender.js coalesces), "path" (snake hook: the anchor follows every point,
// so the points go spaced along the drag as a brush's dabs are).
// Conventions: vu, world axes, y up; a ray is {origin, direction (unit)}; vectors are arrays.

import { DabSpacer } from "./dab-spacer.js";
import { addScaled, dot, length, normalize, sub } from "./vec3.js";

// Where the ray origin + t direction (t >= 0) meets the plane through `point` with normal
// `normal`, or null when it runs parallel to the plane or meets it behind the origin.
export function rayPlane(origin, direction, point, normal) {
  const facing = dot(direction, normal);
  if (Math.abs(facing) < 1e-9) return null;
  const t = dot(sub(point, origin), normal) / facing;
  return t >= 0 ? addScaled(origin, direction, t) : null;
}

// The signed drag of twist, scale and pinch in radii (PROTOCOL.md): the part of the move from
// the anchor to `point` along `direction`, over the radius; without a direction, the move's
// length (the server's default direction is the move's own).
export function warpAmount(anchor, point, direction, radius) {
  const d = sub(point, anchor);
  const along = direction ? dot(d, normalize(direction)) : length(d);
  return along / radius;
}

export class WarpDrag {
  // anchor: the surface point picked at the press; viewNormal: unit, the camera's backward axis
  // (towards the eye), the normal of the plane the pointer moves on; dabs: "anchored" | "path";
  // spacing: vu between a path's points.
  constructor({ anchor, viewNormal, dabs, spacing }) {
    if (dabs !== "anchored" && dabs !== "path") throw new RangeError(`a warp's dabs are "anchored" or "path", not ${dabs}`);
    this.anchor = anchor;
    this.viewNormal = viewNormal;
    this.dabs = dabs;
    this.point = null; // the pointer's newest point on the plane
    this.path = [anchor]; // the points handed out, the anchor first
    // A path's points are spaced along the plane, never broken: the plane has no silhouettes.
    this.spacer = dabs === "path" ? new DabSpacer(spacing, Infinity) : null;
    if (this.spacer) this.spacer.add(anchor, [0, 0], 1);
  }

  // The pointer's ray now: the points to send, in order (the newest point for "anchored"; for
  // "path" the points spaced along the way since the last call, maybe none). A ray that misses
  // the plane (looking along it) gives none.
  move(ray) {
    const p = rayPlane(ray.origin, ray.direction, this.anchor, this.viewNormal);
    if (!p) return [];
    this.point = p;
    const out = this.spacer ? this.spacer.add(p, [0, 0], 1).map((d) => d.point) : [p];
    if (this.dabs === "path") this.path.push(...out);
    else this.path = [this.anchor, p];
    return out;
  }

  // The drag ends: a path's last stretch, shorter than the spacing, as one more point, so the
  // anchor ends where the pointer did; nothing for "anchored" (its newest point went already).
  end() {
    if (!this.spacer || !this.point) return [];
    const last = this.path[this.path.length - 1];
    if (length(sub(this.point, last)) < 1e-6) return [];
    this.path.push(this.point);
    return [this.point];
  }
}
