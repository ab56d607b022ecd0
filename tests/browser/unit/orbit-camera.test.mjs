// web-client/math/orbit-camera.js: the camera both views share. Its rays must be those of the
// server's ray caster (server/engine/raycast.cpp, View::ray) and of its own matrices.
import { test } from "node:test";
import assert from "node:assert/strict";

import { ORTHOGRAPHIC_FOV_DEGREES, OrbitCamera } from "../../../web-client/math/orbit-camera.js";
import { transformPoint } from "../../../web-client/math/mat4.js";
import { addScaled, cross, dot, length, normalize, sub } from "../../../web-client/math/vec3.js";

const close = (a, b, tol, what) => a.forEach((v, i) => assert.ok(Math.abs(v - b[i]) <= tol, `${what}[${i}]: ${v} vs ${b[i]}`));

test("presets put the eye on +z (front), +x (side) and +y (top) of the target", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.target = [10, 20, 30];
  c.distance = 50;
  c.setPreset("front");
  close(c.eye, [10, 20, 80], 1e-9, "front eye");
  c.setPreset("side");
  close(c.eye, [60, 20, 30], 1e-9, "side eye");
  c.setPreset("top");
  close(c.eye, [10, 70, 30], 1e-9, "top eye");
  // Looking straight down, up must still be a valid, perpendicular vector (the server refuses
  // an up parallel to the view).
  assert.ok(Math.abs(dot(c.up, c.backward)) < 1e-12);
  assert.ok(Math.abs(length(c.up) - 1) < 1e-12);
});

test("the eye, up and right form an orthonormal frame at any orbit", () => {
  const c = new OrbitCamera([64, 64, 64]);
  for (const [dx, dy] of [[0, 0], [130, -40], [-500, 900], [33, -2000]]) {
    c.orbit(dx, dy, 600);
    const b = c.backward, u = c.up, r = c.right;
    assert.ok(Math.abs(length(b) - 1) < 1e-12 && Math.abs(length(u) - 1) < 1e-12 && Math.abs(length(r) - 1) < 1e-12);
    assert.ok(Math.abs(dot(b, u)) < 1e-12 && Math.abs(dot(b, r)) < 1e-12 && Math.abs(dot(u, r)) < 1e-12);
    assert.ok(c.pitch <= Math.PI / 2 && c.pitch >= -Math.PI / 2, "pitch never rolls over");
  }
});

test("rays match the server's pinhole: pixel centres, vertical field of view, square pixels", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.fit([20, 20, 20], [100, 100, 100]);
  c.orbit(70, -30, 500);
  const w = 640, h = 480;
  const f = normalize(sub(c.target, c.eye));
  const r = normalize(cross(f, c.up));
  const u = cross(r, f);
  const tanHalf = Math.tan((40 * Math.PI) / 360);
  for (const [x, y] of [[0, 0], [639, 479], [320, 10], [17, 400]]) {
    const sx = ((2 * (x + 0.5)) / w - 1) * tanHalf * (w / h);
    const sy = (1 - (2 * (y + 0.5)) / h) * tanHalf;
    const expected = normalize(addScaled(addScaled(f, r, sx), u, sy));
    const ray = c.ray(x + 0.5, y + 0.5, w, h);
    close(ray.direction, expected, 1e-12, `ray (${x}, ${y})`);
    close(ray.origin, c.eye, 0, "origin");
  }
});

test("a point on a pixel's ray projects back onto that pixel", () => {
  const c = new OrbitCamera([256, 256, 256]);
  c.fit(null, null);
  c.orbit(-200, 90, 700);
  c.update(800, 600);
  for (const [x, y] of [[400, 300], [12.5, 590.5], [799, 1]]) {
    const { origin, direction } = c.ray(x, y, 800, 600);
    const p = transformPoint(c.viewProjection, addScaled(origin, direction, c.distance));
    close([(p[0] + 1) * 400, (1 - p[1]) * 300], [x, y], 1e-3, `pixel (${x}, ${y})`);
    assert.ok(p[2] > -1 && p[2] < 1, "between the clip planes");
  }
});

test("the clip planes hold the whole domain from anywhere the camera may go", () => {
  const c = new OrbitCamera([512, 512, 512]);
  for (const distance of [1, 30, 300, 3000, 1e6]) {
    c.fit(null, null);
    c.distance = distance;
    c.setDomain([512, 512, 512]);
    for (const yaw of [0, 1, 2, 3]) {
      c.yaw = yaw;
      const { near, far } = c.clipPlanes();
      assert.ok(near > 0 && near < far);
      // Every corner of the domain lies before the far plane, along the view axis.
      for (const corner of [[0, 0, 0], [511, 511, 511], [0, 511, 0], [511, 0, 511]]) {
        const along = -dot(sub(corner, c.eye), c.backward);
        assert.ok(along < far, `corner ${corner} at ${along} beyond far ${far} (distance ${c.distance})`);
        if (along > 0 && c.distance > 1000) assert.ok(along > near, "and after the near plane when the eye is outside");
      }
    }
  }
  assert.ok(c.distance <= c.maxDistance && c.distance >= c.minDistance, "zoom is clamped");
});

test("fit frames a box: every corner in view, one of them near the edge", () => {
  const c = new OrbitCamera([128, 128, 128]);
  for (const [aspect, yaw] of [[1, 0.3], [1.6, 1.2], [0.5, -2]]) {
    c.yaw = yaw;
    c.fit([10, 20, 30], [50, 80, 70], aspect);
    close(c.target, [30, 50, 50], 1e-12, "target");
    c.update(aspect * 400, 400); // Float32 matrices: compare to 1e-6
    let extent = 0;
    for (let corner = 0; corner < 8; ++corner) {
      const p = transformPoint(c.viewProjection, [corner & 1 ? 50 : 10, corner & 2 ? 80 : 20, corner & 4 ? 70 : 30]);
      extent = Math.max(extent, Math.abs(p[0]), Math.abs(p[1]));
    }
    assert.ok(extent <= 0.8 + 1e-6 && extent > 0.75, `corners reach ${extent} of the half-view (aspect ${aspect})`);
  }
  const camera = c.toProtocol();
  assert.deepEqual(Object.keys(camera).sort(), ["eye", "fov", "target", "up"]);
  assert.equal(camera.fov, 40);
});

test("fitPoints frames the points themselves, not their box", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.setPreset("front");
  // A thin diagonal rod: its box is much larger than what it covers from the front.
  const rod = new Float32Array([0, 0, 64, 10, 10, 64, 20, 20, 64, 30, 30, 64, 40, 40, 64]);
  c.fitPoints([rod.subarray(0, 6), rod.subarray(6)], 1);
  close(c.target, [20, 20, 64], 1e-12, "target");
  c.update(400, 400);
  const far = transformPoint(c.viewProjection, [40, 40, 64]);
  assert.ok(Math.abs(Math.max(Math.abs(far[0]), Math.abs(far[1])) - 0.8) < 1e-5, `the rod's end at ${far}`);
  const before = c.state();
  c.fitPoints([new Float32Array(0)], 1);
  assert.deepEqual(c.state(), before, "no points: no change");
});

test("zoomAt keeps the point under the pointer (at the target's depth) under the pointer", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.target = [64, 64, 64];
  c.distance = 200;
  c.setPreset("home");
  const [w, h, x, y] = [800, 600, 610, 150];
  const before = c.ray(x, y, w, h);
  const forward = normalize(sub(c.target, c.eye));
  const t = c.distance / dot(before.direction, forward); // to the plane through the target
  const point = addScaled(before.origin, before.direction, t);
  c.zoomAt(0.5, x, y, w, h);
  assert.equal(c.distance, 100);
  const after = c.ray(x, y, w, h);
  const off = sub(point, after.origin);
  const miss = length(sub(off, after.direction.map((v) => v * dot(off, after.direction))));
  assert.ok(miss < 1e-9, `the point is ${miss} vu off the new ray`);
  const target = [...c.target];
  c.zoomAt(2, w / 2, h / 2, w, h);
  assert.equal(c.distance, 200);
  close(c.target, target, 1e-12, "a zoom at the centre keeps the target");
});

test("an orbit around a pivot keeps the pivot where it was on screen and turns the view as a plain orbit does", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.target = [64, 64, 64];
  c.distance = 150;
  c.setPreset("home");
  const pivot = [80, 70, 90];
  const [w, h] = [800, 600];
  const screen = (p) => {
    c.update(w, h);
    const n = transformPoint(c.viewProjection, p);
    return [((n[0] + 1) / 2) * w, ((1 - n[1]) / 2) * h];
  };
  const before = screen(pivot);
  const plain = new OrbitCamera([128, 128, 128]);
  plain.setState(c.state());
  c.orbit(120, -45, h, pivot);
  plain.orbit(120, -45, h);
  close(screen(pivot), before, 1e-3, "pivot on screen (float32 matrices)");
  assert.equal(c.yaw, plain.yaw);
  assert.equal(c.pitch, plain.pitch);
  assert.equal(c.distance, 150);
  assert.ok(length(sub(c.target, [64, 64, 64])) > 1, "the target moved around the pivot");
  c.focus([10, 20, 30]);
  close(c.target, [10, 20, 30], 0, "focus centres the view on the point");
  assert.equal(c.distance, 150, "from the same distance");
});

test("with the model's front on +x (the pig) the presets turn with it: front looks at its face", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.target = [10, 20, 30];
  c.distance = 50;
  c.setFront("+x");
  c.setPreset("front");
  close(c.eye, [60, 20, 30], 1e-9, "front eye");
  c.setPreset("side");
  close(c.eye, [10, 20, -20], 1e-9, "side eye");
  c.setFront("-z");
  c.setPreset("front");
  close(c.eye, [10, 20, -20], 1e-9, "front eye, -z");
  c.setFront(null);
  c.setPreset("front");
  close(c.eye, [10, 20, 80], 1e-9, "front eye, default");
});

test("the orthographic view is a narrow fov from farther away: the target's depth keeps its scale, depth barely changes size", () => {
  const c = new OrbitCamera([128, 128, 128]);
  c.target = [64, 64, 64];
  c.distance = 200;
  const perPixel = c.worldPerPixel(800);
  const [min, max] = [c.minDistance, c.maxDistance];
  c.setOrthographic(true);
  assert.equal(c.orthographic, true);
  assert.equal(c.fovDegrees, ORTHOGRAPHIC_FOV_DEGREES);
  assert.ok(Math.abs(c.worldPerPixel(800) / perPixel - 1) < 1e-12, "the same size on screen at the target");
  const k = c.distance / 200;
  assert.ok(Math.abs(c.minDistance / min - k) < 1e-9 && Math.abs(c.maxDistance / max - k) < 1e-9, "zoom limits follow");
  assert.ok(Math.hypot(...c.eye) < 1e5, "the eye stays where the server accepts cameras");
  // Two points 100 vu apart in depth, same offset sideways: their screen positions differ by
  // under 3% (by 40% in the default perspective view).
  const spread = (cam) => {
    cam.update(800, 800);
    const near = transformPoint(cam.viewProjection, addScaled(addScaled(cam.target, cam.backward, 50), cam.right, 20));
    const far = transformPoint(cam.viewProjection, addScaled(addScaled(cam.target, cam.backward, -50), cam.right, 20));
    return near[0] / far[0] - 1;
  };
  assert.ok(spread(c) > 0 && spread(c) < 0.03, `orthographic: ${spread(c)}`);
  c.setOrthographic(false);
  assert.ok(Math.abs(c.distance - 200) < 1e-9, "and back to where it was");
  assert.ok(spread(c) > 0.4, `perspective: ${spread(c)}`);
});
