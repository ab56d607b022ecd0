// Presence (protocol/PROTOCOL.md, section "Presence", since 1.2): what a client tells the
// session's others of itself (its brush under the pointer, its camera), and the others'
// presence as the server forwards it. Transport-free like rpc.js: the client's net/ layer sends
// `builder.notification("presence", presenceParams(...))` and hands received notifications to a
// PresenceBoard.
//
// Conventions: coordinates in vu of the session grid; presenceParams checks what it is given
// the way the server will (so a programming error throws here instead of being refused
// silently, presence being a notification) and throws TypeError/RangeError; PresenceBoard reads
// untrusted server messages and never throws for their content (it ignores what is malformed).

import { PARAMETERS, TOOL_NAMES } from "./tools.js";

// The names a brush's `tool` may be: every tool of the registry (protocol/registry/tools.json).
export const PRESENCE_TOOLS = TOOL_NAMES;
const RADIUS = PARAMETERS.radius;
// A receiver gets one sender's presence at most this often (ms): sending faster only replaces.
export const PRESENCE_INTERVAL_MS = 50;

const MAX_COORDINATE = 1e6;
const MAX_CAMERA_COORDINATE = 1e5;

function isObject(value) {
  return typeof value === "object" && value !== null && !Array.isArray(value);
}

function vec3(value, what, bound) {
  if (!Array.isArray(value) || value.length !== 3) throw new TypeError(`${what} must be an array [x, y, z]`);
  for (const v of value)
    if (typeof v !== "number" || !Number.isFinite(v) || Math.abs(v) > bound)
      throw new RangeError(`${what} must hold finite numbers within ±${bound}`);
  return [value[0], value[1], value[2]];
}

function onlyKeys(object, allowed, what) {
  for (const key of Object.keys(object))
    if (!allowed.includes(key)) throw new TypeError(`unknown key "${key}" in ${what} (allowed: ${allowed.join(", ")})`);
}

// An sRGB colour on the wire: [r, g, b], three integers 0..255.
export function isRgb(value) {
  return Array.isArray(value) && value.length === 3 && value.every((c) => Number.isInteger(c) && c >= 0 && c <= 255);
}

// The params of a `presence` message: {brush?, camera?}. brush = {tool, radius, point, normal,
// active, color?} (color: the paint colour [r, g, b], which the others draw the ring in);
// camera = {eye, target, up?, fov?} (as view.set's). Each presence replaces the previous one as
// a whole: leave out `brush` when the pointer is off the model.
export function presenceParams({ brush, camera } = {}) {
  const params = {};
  if (brush !== undefined) {
    if (!isObject(brush)) throw new TypeError("brush must be an object {tool, radius, point, normal, active, color?}");
    onlyKeys(brush, ["tool", "radius", "point", "normal", "active", "color"], "a brush");
    if (brush.color !== undefined && !isRgb(brush.color))
      throw new RangeError("brush.color must be [r, g, b], three integers in 0..255");
    if (!PRESENCE_TOOLS.includes(brush.tool)) throw new RangeError(`brush.tool must be one of ${PRESENCE_TOOLS.join(", ")}`);
    if (typeof brush.radius !== "number" || !(brush.radius >= RADIUS.minimum && brush.radius <= RADIUS.maximum))
      throw new RangeError(`brush.radius must be a number in [${RADIUS.minimum}, ${RADIUS.maximum}]`);
    const normal = vec3(brush.normal, "brush.normal", MAX_COORDINATE);
    if (normal.every((v) => v === 0)) throw new RangeError("brush.normal must not be zero");
    if (typeof brush.active !== "boolean") throw new TypeError("brush.active must be a boolean");
    params.brush = {
      tool: brush.tool,
      radius: brush.radius,
      point: vec3(brush.point, "brush.point", MAX_COORDINATE),
      normal,
      active: brush.active,
    };
    if (brush.color !== undefined) params.brush.color = [...brush.color];
  }
  if (camera !== undefined) {
    if (!isObject(camera)) throw new TypeError("camera must be an object {eye, target, up?, fov?}");
    onlyKeys(camera, ["eye", "target", "up", "fov"], "a camera");
    const c = {
      eye: vec3(camera.eye, "camera.eye", MAX_CAMERA_COORDINATE),
      target: vec3(camera.target, "camera.target", MAX_CAMERA_COORDINATE),
    };
    if (c.eye.every((v, i) => v === c.target[i])) throw new RangeError("camera.eye must differ from camera.target");
    if (camera.up !== undefined) c.up = vec3(camera.up, "camera.up", Number.MAX_VALUE);
    if (camera.fov !== undefined) {
      if (typeof camera.fov !== "number" || !(camera.fov > 1 && camera.fov < 170))
        throw new RangeError("camera.fov must be in (1, 170) degrees");
      c.fov = camera.fov;
    }
    params.camera = c;
  }
  return params;
}

// The others of a session as their presence notifications tell them: `others` maps a client id
// to its newest {client, name, color, brush?, camera?}. Events (an EventTarget):
//   "presence": event.presence is the new entry (its brush, camera or both may have changed);
//   "gone": event.client is the id of a client that left (its entry was removed).
// A presence of a client whose last word was "gone" is ignored (PROTOCOL.md explains the order).
export class PresenceBoard extends EventTarget {
  #others = new Map();
  #gone = new Set();

  get others() {
    return this.#others;
  }

  // Takes one notification ({method, params}, as classifyMessage gives it). True when it was a
  // well-formed presence notification and was applied.
  handle(notification) {
    if (notification?.method !== "presence" || !isObject(notification.params)) return false;
    const p = notification.params;
    if (!Number.isSafeInteger(p.client) || p.client < 1) return false;
    if (p.gone === true) {
      this.#others.delete(p.client);
      this.#gone.add(p.client);
      const event = new Event("gone");
      event.client = p.client;
      this.dispatchEvent(event);
      return true;
    }
    if (this.#gone.has(p.client) || typeof p.name !== "string" || typeof p.color !== "string") return false;
    if (p.brush !== undefined && !isObject(p.brush)) return false;
    if (p.camera !== undefined && !isObject(p.camera)) return false;
    const entry = { client: p.client, name: p.name, color: p.color };
    if (p.brush !== undefined) entry.brush = p.brush;
    if (p.camera !== undefined) entry.camera = p.camera;
    this.#others.set(p.client, entry);
    const event = new Event("presence");
    event.presence = entry;
    this.dispatchEvent(event);
    return true;
  }

  // Forgets everyone (after leaving the session).
  clear() {
    this.#others.clear();
    this.#gone.clear();
  }
}
