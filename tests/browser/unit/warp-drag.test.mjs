// web-client/math/warp-drag.js: the pointer's point of a warp stroke (the ray met with the plane
// through the anchor facing the camera), the points an anchored and a path drag hand out, and
// the signed drag of twist, scale and pinch; with the camera's screen-right axis, their
// direction.
import { test } from "node:test";
import assert from "node:assert/strict";

import { OrbitCamera } from "../../../web-client/math/orbit-camera.js";
import { transformPoint } from "../../../web-client/math/mat4.js";
import { rayPlane, WarpDrag, warpAmount } from "../../../web-client/math/warp-drag.js";

const close = (a, b, eps, what) => a.forEach((v, i) => assert.ok(Math.abs(v - b[i]) <= eps, `${what}: ${JSON.stringify(a)} vs ${JSON.stringify(b)}`));

test("a ray meets a plane where t solves (o + t d - p) . n = 0, never behind its origin nor along the plane", () => {
  // the plane z = 5 facing +z, rays from the origin
  assert.deepEqual(rayPlane([0, 0, 0], [0, 0, 1], [3, 4, 5], [0, 0, 1]), [0, 0, 5]);
  const d = [3 / 13, 4 / 13, 12 / 13];
  close(rayPlane([1, 2, 0], d, [0, 0, 6], [0, 0, -1]), [1 + 1.5, 2 + 2, 6], 1e-12, "slanted ray: t = 6 / (12/13) = 6.5");
  // a slanted plane: x + y = 10 through (5, 5, 0)
  const n = [Math.SQRT1_2, Math.SQRT1_2, 0];
  close(rayPlane([0, 0, 7], [1, 0, 0], [5, 5, 0], n), [10, 0, 7], 1e-12, "x + y = 10");
  assert.equal(rayPlane([0, 0, 0], [0, 0, -1], [0, 0, 5], [0, 0, 1]), null, "the plane behind the ray");
  assert.equal(rayPlane([0, 0, 0], [1, 0, 0], [0, 0, 5], [0, 0, 1]), null, "a ray along the plane");
});

test("grab is direct: the point under any pixel lies on the plane through the anchor facing the camera and projects back onto that pixel", () => {
  const camera = new OrbitCamera([128, 128, 128]);
  camera.target = [63.5, 63.5, 63.5];
  camera.distance = 180;
  camera.yaw = 0.7;
  camera.pitch = 0.3;
  const [w, h] = [800, 600];
  camera.update(w, h);
  const anchor = [80, 70, 90];
  const drag = new WarpDrag({ anchor, viewNormal: camera.backward, dabs: "anchored", spacing: 2 });
  for (const [x, y] of [[400, 300], [10, 20], [790, 590], [512.5, 77.25]]) {
    const ray = camera.ray(x, y, w, h);
    const [p] = drag.move(ray);
    const offPlane = camera.backward.reduce((s, v, i) => s + v * (p[i] - anchor[i]), 0);
    assert.ok(Math.abs(offPlane) < 1e-9, `on the plane: ${offPlane}`);
    const [nx, ny] = transformPoint(camera.viewProjection, p);
    close([((nx + 1) / 2) * w, ((1 - ny) / 2) * h], [x, y], 1e-3, "projects onto the pixel (the matrices are float32)");
  }
});

test("the camera's right axis is the screen's: a point moved along it moves right on screen, not up or down", () => {
  const camera = new OrbitCamera([128, 128, 128]);
  camera.target = [60, 50, 40];
  camera.distance = 150;
  for (const [yaw, pitch] of [[0, 0], [Math.PI / 2, 0], [0.9, 0.6], [-2.5, -1.2], [0.3, Math.PI / 2]]) {
    camera.yaw = yaw;
    camera.pitch = pitch;
    camera.update(640, 480);
    const right = camera.right;
    assert.ok(Math.abs(Math.hypot(...right) - 1) < 1e-12, "unit");
    assert.ok(Math.abs(right.reduce((s, v, i) => s + v * camera.backward[i], 0)) < 1e-12, "in the screen's plane");
    const [ax, ay] = transformPoint(camera.viewProjection, camera.target);
    const [bx, by] = transformPoint(camera.viewProjection, camera.target.map((v, i) => v + 10 * right[i]));
    assert.ok(bx - ax > 0.01, `yaw ${yaw} pitch ${pitch}: moves right (${bx - ax})`);
    assert.ok(Math.abs(by - ay) < 1e-6, `yaw ${yaw} pitch ${pitch}: stays level (${by - ay})`);
  }
});

test("an anchored drag hands out the newest point only; a path drag every point a spacing apart, and its last stretch at the end", () => {
  const ray = (x, y) => ({ origin: [x, y, 50], direction: [0, 0, -1] });
  const grab = new WarpDrag({ anchor: [0, 0, 10], viewNormal: [0, 0, 1], dabs: "anchored", spacing: 2 });
  assert.deepEqual(grab.move(ray(3, 4)), [[3, 4, 10]]);
  assert.deepEqual(grab.move(ray(30, 0)), [[30, 0, 10]], "a long move is still one point");
  assert.deepEqual(grab.path, [[0, 0, 10], [30, 0, 10]]);
  assert.deepEqual(grab.end(), [], "nothing left at the end");

  const snake = new WarpDrag({ anchor: [0, 0, 10], viewNormal: [0, 0, 1], dabs: "path", spacing: 2 });
  assert.deepEqual(snake.move(ray(1, 0)), [], "under the spacing: nothing yet");
  assert.deepEqual(snake.move(ray(7, 0)), [[2, 0, 10], [4, 0, 10], [6, 0, 10]]);
  assert.deepEqual(snake.move(ray(7, 3)), [[7, 1, 10], [7, 3, 10]], "spaced along the way, around the corner");
  assert.deepEqual(snake.end(), [], "the pointer ended on the last point");
  snake.move(ray(7, 4));
  assert.deepEqual(snake.end(), [[7, 4, 10]], "the last stretch");
  assert.deepEqual(snake.path.at(-1), [7, 4, 10]);
  assert.equal(snake.path.length, 1 + 3 + 2 + 1);
  assert.deepEqual(snake.move({ origin: [0, 0, 50], direction: [1, 0, 0] }), [], "a ray along the plane gives nothing");
  assert.throws(() => new WarpDrag({ anchor: [0, 0, 0], viewNormal: [0, 0, 1], dabs: "swept", spacing: 1 }), RangeError);
});

test("twist, scale and pinch read the drag along the direction in radii; without one, its length", () => {
  assert.equal(warpAmount([1, 2, 3], [9, 2, 3], [1, 0, 0], 8), 1);
  assert.equal(warpAmount([1, 2, 3], [-3, 2, 3], [2, 0, 0], 8), -0.5, "dragging left: negative; the direction's length does not count");
  assert.equal(warpAmount([0, 0, 0], [4, 7, 0], [1, 0, 0], 4), 1, "only the part along the direction");
  assert.equal(warpAmount([0, 0, 0], [3, 4, 0], null, 10), 0.5);
});
