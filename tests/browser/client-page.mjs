// What the web client's end-to-end test files share (client*.test.mjs, one ctest entry each so
// that ctest -j can run them beside other tests): reading the page and its pixels, drags,
// sessions. Each file calls useServerAndBrowser() once: its own `marzipan serve` and Chromium
// with a touch screen (harness.mjs serverAndBrowser), started before its first test and closed
// after its last.
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { drawn, ensureArtifactsDir, LOW_DENSITY, serverAndBrowser, settled } from "./harness.mjs";
import { decodePng } from "./png.mjs";

export { drawn, LOW_DENSITY };

export const artifacts = ensureArtifactsDir();

// The file's server and browser ({server, browser}, set once its tests run).
export let env = null;

// hintDismissed: the files other than client.test.mjs ran, while they were one file with it,
// in the browser profile whose hint its first test had dismissed for good; so their pages
// start, the hint not over the pixels they read.
// deviceScaleFactor: below 1 for a file that reads no pixel measure at the page's size in device
// pixels (LOW_DENSITY where it reads no pixels at all; lowDensity() for part of a file).
export function useServerAndBrowser({ hintDismissed = false, deviceScaleFactor = 1 } = {}) {
  env = serverAndBrowser({ hasTouch: true, deviceScaleFactor, localStorage: hintDismissed ? { "marzipan.hint-dismissed": "dismissed" } : {} });
}

// Gives `page`'s screen `deviceScaleFactor` device pixels per CSS pixel, its CSS size (the
// context's viewport) unchanged, through `cdp` (a CDP session of the page). The override stays
// set for the page's life: leaving it would drop the viewport's size too. It does not wait for
// the page to take it: a page not yet loaded has nothing to wait for.
export async function screenDensity(page, cdp, deviceScaleFactor) {
  const { width, height } = page.viewportSize();
  await cdp.send("Emulation.setDeviceMetricsOverride", { width, height, deviceScaleFactor, mobile: false });
}

// Sets `page`'s screen to LOW_DENSITY, for a part of a file that measures no pixels; the
// returned function gives it back density 1 and resolves once the canvas has its full size in
// device pixels again.
export async function lowDensity(page) {
  const cdp = await env.browser.context.newCDPSession(page);
  const { width, height } = page.viewportSize();
  const density = async (deviceScaleFactor) => {
    await screenDensity(page, cdp, deviceScaleFactor);
    await page.evaluate(() => window.marzipan.renderer.requestRedraw());
    await page.waitForFunction(
      ([d, w, h]) => {
        const c = document.getElementById("view");
        return devicePixelRatio === d && innerWidth === w && innerHeight === h && c.width === Math.round(c.clientWidth * d);
      },
      [deviceScaleFactor, width, height],
    );
  };
  await density(LOW_DENSITY);
  return () => density(1);
}

// --- reading the page ------------------------------------------------------------------------

export const text = (page, id) => page.locator(`#${id}`).textContent();
export const data = (page, id, key) => page.evaluate(([i, k]) => document.getElementById(i).dataset[k], [id, key]);

// The picture the canvas draws: the HTML over it that says who else is in the session (the
// people list, the name labels over their rings; web-client/ui/presence-view.js) is hidden for
// the shot, since the checks below read the model and the backdrop from its pixels.
const CANVAS_ONLY = ".people, .presence-labels { visibility: hidden !important; }";

export async function shot(page, name) {
  const png = await page.locator("#view").screenshot({ style: CANVAS_ONLY });
  writeFileSync(join(artifacts, `${name}.png`), png);
  return decodePng(png);
}

// Pixels of the canvas that differ from the backdrop. The backdrop is a vertical gradient, the
// same along each row, so each row's first pixel (left edge, never the model here) is its
// reference.
export function modelFraction(img, box = [0, 0, 1, 1]) {
  const [x0, y0, x1, y1] = [box[0] * img.width, box[1] * img.height, box[2] * img.width, box[3] * img.height].map(Math.round);
  let model = 0;
  for (let y = y0; y < y1; ++y) {
    const ref = y * img.width * 4;
    for (let x = x0; x < x1; ++x) {
      const o = (y * img.width + x) * 4;
      const d = Math.max(...[0, 1, 2].map((c) => Math.abs(img.rgba[o + c] - img.rgba[ref + c])));
      if (d > 12) ++model;
    }
  }
  return model / Math.max(1, (x1 - x0) * (y1 - y0));
}

export function changedPixels(a, b, threshold = 24) {
  assert.equal(a.width, b.width);
  assert.equal(a.height, b.height);
  let n = 0;
  for (let i = 0; i < a.rgba.length; i += 4) {
    const d = Math.max(Math.abs(a.rgba[i] - b.rgba[i]), Math.abs(a.rgba[i + 1] - b.rgba[i + 1]), Math.abs(a.rgba[i + 2] - b.rgba[i + 2]));
    if (d > threshold) ++n;
  }
  return n;
}

// The canvas's centre in page coordinates.
export async function canvasCenter(page) {
  const box = await page.locator("#view").boundingBox();
  return [box.x + box.width / 2, box.y + box.height / 2];
}

export async function drag(page, from, to, steps = 20) {
  await page.mouse.move(from[0], from[1]);
  await page.mouse.down();
  for (let i = 1; i <= steps; ++i)
    await page.mouse.move(from[0] + ((to[0] - from[0]) * i) / steps, from[1] + ((to[1] - from[1]) * i) / steps);
  await page.mouse.up();
}

export async function createSession(page, size, solid) {
  await page.goto(`${env.server.url}/`);
  await page.selectOption("#create-size", String(size));
  await page.selectOption("#create-solid", solid);
  await page.click("#create-button");
  await settled(page, 60000);
}

// A new page on a new session (createSession), with its script errors collected into `errors`
// and every JSON message it sends over the WebSocket, parsed, into `sent` (in order).
export async function sessionPage(size, solid) {
  const errors = [];
  const page = await env.browser.context.newPage();
  collectErrors(page, errors);
  const sent = [];
  page.on("websocket", (ws) => ws.on("framesent", (f) => typeof f.payload === "string" && sent.push(JSON.parse(f.payload))));
  await createSession(page, size, solid);
  return { page, errors, sent };
}

export function collectErrors(page, into) {
  page.on("pageerror", (e) => into.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error") into.push(`console: ${m.text()}`);
  });
}

// Binary STL: an 80-byte header, u32 n, n triangles of 50 bytes (normal, three vertices as
// float32, u16 attribute). Checks the length and that every vertex lies within the grid.
export function checkStl(bytes, size) {
  assert.ok(bytes.length >= 84, `an STL file of ${bytes.length} bytes`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const n = view.getUint32(80, true);
  assert.equal(bytes.length, 84 + 50 * n, "STL length is 84 + 50 n");
  assert.ok(n > 1000, `a sphere of radius 45 vu has more than 1000 triangles, got ${n}`);
  for (let t = 0; t < n; ++t)
    for (let k = 3; k < 12; ++k) {
      const v = view.getFloat32(84 + 50 * t + 4 * k, true);
      assert.ok(Number.isFinite(v) && v >= -1 && v <= size, `vertex coordinate ${v} of triangle ${t}`);
    }
  return n;
}

// The groove close-up's rim roughness and the snout's ripple (rim.mjs) that discs with varying
// normals stay under and discs with one flat normal exceed (measured 2026-11-25, headless
// Chromium + SwiftShader: web-client/README.md, View).
export const RIM_LIMIT = 0.05;
export const RIPPLE_LIMIT = 3.5;

// The mean absolute step of luminance between horizontally and vertically neighbouring pixels
// in `box` (fractions of the picture): what the edges of opaque discs add to a smooth surface.
export function roughness(img, box) {
  const [x0, y0, x1, y1] = [box[0] * img.width, box[1] * img.height, box[2] * img.width, box[3] * img.height].map(Math.round);
  const lum = (x, y) => {
    const o = (y * img.width + x) * 4;
    return 0.2126 * img.rgba[o] + 0.7152 * img.rgba[o + 1] + 0.0722 * img.rgba[o + 2];
  };
  let sum = 0;
  let n = 0;
  for (let y = y0; y < y1; ++y)
    for (let x = x0; x < x1; ++x, n += 2) sum += Math.abs(lum(x + 1, y) - lum(x, y)) + Math.abs(lum(x, y + 1) - lum(x, y));
  return sum / n;
}

// The farthest splat from `center`, vu: how far a stroke raised a sphere's surface.
export const reach = (page, center) =>
  page.evaluate((c) => {
    let far = 0;
    for (const b of window.marzipan.store.bricks.values())
      for (let i = 0; i < 3 * b.count; i += 3) far = Math.max(far, Math.hypot(b.positions[i] - c[0], b.positions[i + 1] - c[1], b.positions[i + 2] - c[2]));
    return far;
  }, center);

// A scrub: the pointer goes back and forth `passes` times over `half` px either side of (x, y).
export async function scrub(page, [x, y], half, passes) {
  await page.mouse.move(x - half, y);
  await page.mouse.down();
  for (let p = 0; p < passes; ++p)
    for (let i = 1; i <= 8; ++i) await page.mouse.move(x + (p % 2 ? 1 : -1) * half * (1 - (2 * i) / 8), y);
  await page.mouse.up();
}
