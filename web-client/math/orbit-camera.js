// An orbit camera around a target point, the one camera of both views: the splat view draws
// with its matrices, the frame view sends it to the server as a ray-cast camera.
// Conventions: world in vu of the session grid, y up; angles in radians. yaw 0 and pitch 0 put
// the eye on the +z side of the target (the "front" view); yaw turns it towards +x ("side"),
// pitch towards +y ("top"). Pitch stays within [-pi/2, pi/2], so the camera never rolls over;
// `up` is the camera's own up vector, never parallel to the view direction (the server refuses
// such cameras). Pixel coordinates have y down from the top-left, as in pointer events.

import * as mat4 from "./mat4.js";
import { addScaled, cross, length, normalize, sub } from "./vec3.js";

export const DEFAULT_FOV_DEGREES = 40; // the server's default, so both views frame alike
// The "orthographic" view is a telephoto: the server ray-casts only perspective cameras (fov
// in (1, 170) degrees) and both views must show the same picture, so the camera narrows to
// this fov and backs off to keep the framing; across a model as deep as the view is high,
// sizes then differ by about 2 tan(fov / 2) ~ 2% from its near side to its far side.
export const ORTHOGRAPHIC_FOV_DEGREES = 1.2;
const HALF_PI = Math.PI / 2;
const FIT_MARGIN = 0.8; // a fitted box fills at most this much of the view's half-extent

export const VIEW_PRESETS = Object.freeze({
  front: { yaw: 0, pitch: 0 },
  side: { yaw: HALF_PI, pitch: 0 },
  top: { yaw: 0, pitch: HALF_PI },
  home: { yaw: Math.PI / 5, pitch: Math.PI / 7 },
});

// The yaw that puts the eye on the side of a horizontal axis ("+x", "-x", "+z", "-z"): the
// model's front, where its face is (the pig of server/engine/solids.hpp faces +x).
const FRONT_YAWS = Object.freeze({ "+z": 0, "+x": HALF_PI, "-z": Math.PI, "-x": -HALF_PI });
export const FRONT_AXES = Object.freeze(Object.keys(FRONT_YAWS));

export class OrbitCamera {
  constructor(dims = [128, 128, 128]) {
    this.fovDegrees = DEFAULT_FOV_DEGREES;
    this.frontYaw = 0; // presets turn by this: the model's front (setFront)
    this.target = [0, 0, 0];
    this.distance = 1;
    this.yaw = VIEW_PRESETS.home.yaw;
    this.pitch = VIEW_PRESETS.home.pitch;
    this.setDomain(dims);
    this.view = mat4.create();
    this.projection = mat4.create();
    this.viewProjection = mat4.create();
  }

  // The session grid: limits zoom and sets the clip planes so that nothing inside the domain is
  // ever clipped, whatever the orbit.
  setDomain(dims) {
    this.dims = [...dims];
    this.domainCenter = dims.map((n) => (n - 1) / 2);
    // Foot points may sit up to 2 vu outside the outermost voxels.
    this.domainRadius = 0.5 * Math.hypot(dims[0], dims[1], dims[2]) + 2;
    this.minDistance = Math.max(1, 0.02 * Math.max(...dims)) * this.#lens;
    this.maxDistance = 8 * this.domainRadius * this.#lens;
    this.distance = clamp(this.distance, this.minDistance, this.maxDistance);
  }

  // How much farther this fov must stand than the default one to frame alike.
  get #lens() {
    return Math.tan((DEFAULT_FOV_DEGREES * Math.PI) / 360) / Math.tan((this.fovDegrees * Math.PI) / 360);
  }

  get orthographic() {
    return this.fovDegrees === ORTHOGRAPHIC_FOV_DEGREES;
  }

  // Switches between the perspective and the (telephoto) orthographic view, keeping what is
  // at the target's depth the same size on screen.
  setOrthographic(on) {
    this.#setFov(on ? ORTHOGRAPHIC_FOV_DEGREES : DEFAULT_FOV_DEGREES);
  }

  #setFov(degrees) {
    const before = this.#lens;
    this.fovDegrees = degrees;
    const k = this.#lens / before;
    this.minDistance *= k;
    this.maxDistance *= k;
    this.distance *= k;
  }

  // The model's front: one of FRONT_AXES, or null for +z (the front preset's own axis).
  setFront(axis) {
    this.frontYaw = FRONT_YAWS[axis] || 0;
  }

  get fovY() {
    return (this.fovDegrees * Math.PI) / 180;
  }

  // Unit vector from the target towards the eye.
  get backward() {
    const cp = Math.cos(this.pitch);
    return [cp * Math.sin(this.yaw), Math.sin(this.pitch), cp * Math.cos(this.yaw)];
  }

  get eye() {
    return addScaled(this.target, this.backward, this.distance);
  }

  get up() {
    const sp = Math.sin(this.pitch);
    return [-sp * Math.sin(this.yaw), Math.cos(this.pitch), -sp * Math.cos(this.yaw)];
  }

  get right() {
    return normalize(cross(this.up, this.backward));
  }

  // Frames the box [lo, hi] (vu) as seen from the current direction in a viewport of the given
  // aspect (width / height): the target goes to the box's centre and the eye just far enough
  // back that all eight corners are in view with a margin. No box frames the whole domain.
  fit(lo, hi, aspect = 1) {
    const box = lo && hi ? [lo, hi] : [[0, 0, 0], this.dims.map((n) => n - 1)];
    const corners = new Float32Array(24);
    for (let c = 0; c < 8; ++c) for (let k = 0; k < 3; ++k) corners[3 * c + k] = box[(c >> k) & 1][k];
    this.fitPoints([corners], aspect);
  }

  // The same for a cloud of points (Float32Arrays of x, y, z per point): the target goes to the
  // centre of their box and every point is in view, so the model itself fills the view rather
  // than its bounding box. Nothing happens for no points.
  fitPoints(arrays, aspect = 1) {
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (const a of arrays)
      for (let i = 0; i < a.length; i += 3)
        for (let k = 0; k < 3; ++k) {
          lo[k] = Math.min(lo[k], a[i + k]);
          hi[k] = Math.max(hi[k], a[i + k]);
        }
    if (!(lo[0] <= hi[0])) return;
    const t = lo.map((v, k) => (v + hi[k]) / 2);
    const tanV = FIT_MARGIN * Math.tan(this.fovY / 2);
    const tanH = tanV * aspect;
    const [r, u, b] = [this.right, this.up, this.backward];
    let distance = 1;
    for (const a of arrays)
      for (let i = 0; i < a.length; i += 3) {
        const x = a[i] - t[0], y = a[i + 1] - t[1], z = a[i + 2] - t[2];
        const along = x * b[0] + y * b[1] + z * b[2];
        const sideways = Math.abs(x * r[0] + y * r[1] + z * r[2]) / tanH;
        const upwards = Math.abs(x * u[0] + y * u[1] + z * u[2]) / tanV;
        distance = Math.max(distance, along + sideways, along + upwards);
      }
    this.target = t;
    this.distance = clamp(distance, this.minDistance, this.maxDistance);
  }

  setPreset(name) {
    const p = VIEW_PRESETS[name];
    this.yaw = wrapAngle(p.yaw + this.frontYaw);
    this.pitch = p.pitch;
  }

  // Drag by (dx, dy) pixels in a viewport `height` pixels tall: a full height turns by 180 deg.
  // With a `pivot` (vu), the camera turns around that point instead of the target, and the
  // pivot stays where it is on screen (the point a sculptor orbits to look at stays put).
  orbit(dx, dy, height, pivot = null) {
    const before = pivot && this.#cameraCoordinates(pivot);
    const k = Math.PI / Math.max(1, height);
    this.yaw = wrapAngle(this.yaw - dx * k);
    this.pitch = clamp(this.pitch + dy * k, -HALF_PI, HALF_PI);
    if (before) {
      const [r, u, b] = [this.right, this.up, this.backward];
      const eye = pivot.map((p, i) => p - (before[0] * r[i] + before[1] * u[i] + before[2] * b[i]));
      this.target = addScaled(eye, b, -this.distance);
    }
  }

  // (pivot − eye) in the camera's right, up, backward axes.
  #cameraCoordinates(p) {
    const d = sub(p, this.eye);
    return [this.right, this.up, this.backward].map((a) => d[0] * a[0] + d[1] * a[1] + d[2] * a[2]);
  }

  // Centres the view on `point` (vu) from the same direction and distance (double-click focus).
  focus(point) {
    this.target = point.map((v, i) => clamp(v, -this.dims[i], 2 * this.dims[i]));
  }

  // Moves the target so that the point under the cursor follows it (at the target's depth).
  pan(dx, dy, height) {
    const perPixel = this.worldPerPixel(height);
    this.target = addScaled(addScaled(this.target, this.right, -dx * perPixel), this.up, dy * perPixel);
    this.target = this.target.map((v, i) => clamp(v, -this.dims[i], 2 * this.dims[i]));
  }

  // factor < 1 moves closer.
  zoom(factor) {
    this.distance = clamp(this.distance * factor, this.minDistance, this.maxDistance);
  }

  // Zooms by `factor` towards the pixel (x, y) of a width x height viewport: the point under it
  // at the target's depth stays under it, so a sculptor zooms into the detail under the pointer.
  zoomAt(factor, x, y, width, height) {
    const perPixel = this.worldPerPixel(height);
    const before = this.distance;
    this.zoom(factor);
    const moved = 1 - this.distance / before;
    const sx = (x - width / 2) * perPixel * moved;
    const sy = (y - height / 2) * perPixel * moved;
    this.target = addScaled(addScaled(this.target, this.right, sx), this.up, -sy);
    this.target = this.target.map((v, i) => clamp(v, -this.dims[i], 2 * this.dims[i]));
  }

  // Size of one pixel at the target's depth, in vu.
  worldPerPixel(height) {
    return (2 * this.distance * Math.tan(this.fovY / 2)) / Math.max(1, height);
  }

  // Clip planes that hold the whole domain: beyond its far side is nothing to draw, and the
  // near plane comes as close as depth precision allows when the eye is inside the domain.
  clipPlanes() {
    const dc = length(sub(this.eye, this.domainCenter));
    const far = dc + this.domainRadius;
    const near = Math.max(dc - this.domainRadius, far / 4000, 0.05);
    return { near, far };
  }

  // Updates view, projection and viewProjection for a viewport of width x height pixels.
  update(width, height) {
    const { near, far } = this.clipPlanes();
    mat4.lookAt(this.view, this.eye, this.target, this.up);
    mat4.perspective(this.projection, this.fovY, width / Math.max(1, height), near, far);
    mat4.multiply(this.viewProjection, this.projection, this.view);
    return this;
  }

  // The ray through pixel (x, y) of a width x height viewport (continuous coordinates: the
  // centre of pixel (i, j) is (i + 0.5, j + 0.5)): {origin, direction (unit)}.
  ray(x, y, width, height) {
    const t = Math.tan(this.fovY / 2);
    const sx = ((2 * x) / width - 1) * t * (width / height);
    const sy = (1 - (2 * y) / height) * t;
    const forward = this.backward.map((v) => -v);
    const dir = addScaled(addScaled(forward, this.right, sx), this.up, sy);
    return { origin: this.eye, direction: normalize(dir) };
  }

  // The camera object of PROTOCOL.md (view.set, render.frame).
  toProtocol() {
    return { eye: this.eye, target: [...this.target], up: this.up, fov: this.fovDegrees };
  }

  // Takes the camera object of PROTOCOL.md (another client's, for following it): the same eye,
  // target and fov; yaw and pitch from the view direction, and at the poles (looking straight
  // down or up, where the direction says nothing of the yaw) from `up`. The distance is kept
  // within this camera's limits (the same grid gives the same limits). A camera that rolls
  // (an `up` off the plane of the view direction and y) cannot be an orbit camera's: its roll
  // is dropped.
  setFromProtocol({ eye, target, up = [0, 1, 0], fov = DEFAULT_FOV_DEGREES }) {
    if (fov !== this.fovDegrees) this.#setFov(fov);
    const d = sub(eye, target);
    const distance = length(d);
    const b = d.map((v) => v / distance);
    this.pitch = Math.asin(clamp(b[1], -1, 1));
    const horizontal = Math.hypot(b[0], b[2]);
    // up = (-sin(pitch) sin(yaw), cos(pitch), -sin(pitch) cos(yaw)) (see `up`)
    if (horizontal > 1e-6) this.yaw = Math.atan2(b[0], b[2]);
    else this.yaw = b[1] > 0 ? Math.atan2(-up[0], -up[2]) : Math.atan2(up[0], up[2]);
    this.target = [...target];
    this.distance = clamp(distance, this.minDistance, this.maxDistance);
  }

  // A plain copy of the orbit state, and back: for change detection and resets.
  state() {
    return { target: [...this.target], distance: this.distance, yaw: this.yaw, pitch: this.pitch };
  }

  setState(s) {
    this.target = [...s.target];
    this.distance = clamp(s.distance, this.minDistance, this.maxDistance);
    this.yaw = s.yaw;
    this.pitch = clamp(s.pitch, -HALF_PI, HALF_PI);
  }
}

function clamp(v, lo, hi) {
  return Math.min(hi, Math.max(lo, v));
}

function wrapAngle(a) {
  return a - 2 * Math.PI * Math.floor((a + Math.PI) / (2 * Math.PI));
}
