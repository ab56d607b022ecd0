// The web client end to end (as client.test.mjs): paint and mask (issue 30). A paint stroke on
// the sphere colours the pixels under it; a masked area keeps its pixels while a blob is added
// over it; Alt+click picks the colour under the pointer into the paint colour; the ring of a
// painting collaborator shows in the paint colour.
// Conventions: pixel positions in CSS pixels of the page; screenshots go to
// MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";

import { canvasCenter, collectErrors, createSession, drag, env, sessionPage, shot, useServerAndBrowser } from "./client-page.mjs";
import { revision, settled } from "./harness.mjs";

useServerAndBrowser({ hintDismissed: true });

// The mean colour of the canvas picture over a square of half side `half` px around (x, y),
// (x, y) in CSS pixels of the canvas (its picture has as many pixels: device scale 1).
function meanColor(img, [x, y], half) {
  const sum = [0, 0, 0];
  let n = 0;
  for (let j = Math.round(y - half); j <= Math.round(y + half); ++j)
    for (let i = Math.round(x - half); i <= Math.round(x + half); ++i) {
      const o = (j * img.width + i) * 4;
      for (let c = 0; c < 3; ++c) sum[c] += img.rgba[o + c];
      ++n;
    }
  return sum.map((s) => s / n);
}

async function changed(page, before) {
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, before);
  await settled(page);
}

test("a paint stroke colours the clay under it, a mask keeps an area as it was, Alt+click picks the colour", { timeout: 300000 }, async () => {
  const { page, errors, sent } = await sessionPage(96, "sphere");
  const canvas = await page.locator("#view").boundingBox();
  const [cx, cy] = await canvasCenter(page); // page coordinates
  const local = ([x, y]) => [x - canvas.x, y - canvas.y];
  const pick = (at) => page.evaluate(([x, y]) => window.marzipan.sculpt.pick(x, y), local(at));
  // CSS pixels per vu about the middle of the view, where the sphere faces the camera.
  const [h0, h1] = [await pick([cx, cy]), await pick([cx + 40, cy])];
  const s = 40 / Math.hypot(...h1.point.map((v, k) => v - h0.point[k]));
  const at = (dx, dy) => [cx + dx * s, cy + dy * s]; // dx, dy in vu on screen
  await page.mouse.move(5, 5); // no brush cursor in the pictures
  const before = await shot(page, "30-paint-before");
  const clay = meanColor(before, local(at(-6, 0)), 2);
  assert.ok(clay[0] > clay[2] + 20 && clay[1] > clay[2], `the sphere shows clay: ${clay.map(Math.round)}`);

  // The Paint group's tools come from the registry; paint sends the colour of the input.
  await page.click('label:has(input[value="paint"])');
  assert.equal(await page.locator("#paint-color-row").isVisible(), true, "the paint tool shows its colour");
  await page.locator("#paint-color").fill("#1e3cdc"); // a blue far from the clay
  await page.locator("#radius").fill("3");
  await page.locator("#strength").fill("1");
  let r = await revision(page);
  let from = sent.length;
  await drag(page, at(-5, 0), at(5, 0), 16);
  await changed(page, r);
  const [begin] = sent.slice(from).filter((m) => m.method === "stroke.begin");
  assert.deepEqual(begin.params.color, [30, 60, 220], "stroke.begin carries the paint colour");
  assert.equal(begin.params.tool, "paint");
  await page.mouse.move(5, 5);
  const painted = await shot(page, "31-painted-stripe");
  const under = meanColor(painted, local([cx, cy]), 2);
  assert.ok(under[2] > under[0] + 40 && under[2] > under[1] + 20, `the stripe is blue: ${under.map(Math.round)}`);
  const beside = meanColor(painted, local(at(0, -10)), 2);
  const besideBefore = meanColor(before, local(at(0, -10)), 2);
  assert.ok(beside.every((c, k) => Math.abs(c - besideBefore[k]) < 4), `away from the stripe the clay is as before: ${beside.map(Math.round)}`);

  // Alt+click beside the stripe picks the clay's colour, on the stripe its blue.
  await page.keyboard.down("Alt");
  await page.mouse.click(...at(0, -10));
  await page.keyboard.up("Alt");
  const picked = await page.evaluate(() => window.marzipan.controls.settings.paintColor);
  const base = await page.evaluate(() => window.marzipan.session.info.base_color);
  assert.deepEqual(picked, base, "Alt+click on unpainted clay picks the session's base colour");
  await page.keyboard.down("Alt");
  await page.mouse.click(cx, cy);
  await page.keyboard.up("Alt");
  assert.deepEqual(await page.evaluate(() => window.marzipan.controls.settings.paintColor), [30, 60, 220], "Alt+click on the stripe picks its blue");
  assert.equal(await page.locator("#paint-color").inputValue(), "#1e3cdc");

  // Mask a spot (radius 4 vu) left of the stripe, then drag a blob over it and on past it: the
  // masked pixels stay as they were and the surface there does not move; past the mask it rises.
  const spot = at(-12, 8), past = at(-12, 15);
  await page.click('label:has(input[value="mask"])');
  await page.locator("#radius").fill("4");
  r = await revision(page);
  await drag(page, spot, [spot[0] + 1, spot[1]], 2);
  await changed(page, r);
  await page.mouse.move(5, 5);
  const masked = await shot(page, "32-masked");
  const maskedPixel = meanColor(masked, local(spot), 1);
  const unmaskedBefore = meanColor(before, local(spot), 1);
  assert.ok(maskedPixel.every((c, k) => c < unmaskedBefore[k] - 8), `masked clay is darker: ${maskedPixel.map(Math.round)} vs ${unmaskedBefore.map(Math.round)}`);
  const [spotDepth, pastDepth] = [(await pick(spot)).t, (await pick(past)).t];
  await page.click('label:has(input[value="add_blob"])');
  await page.locator("#radius").fill("4");
  r = await revision(page);
  await drag(page, at(-12, 2), at(-12, 17), 12);
  await changed(page, r);
  await page.mouse.move(5, 5);
  const blobbed = await shot(page, "33-blob-over-mask");
  const keep = meanColor(blobbed, local(spot), 1);
  assert.ok(keep.every((c, k) => Math.abs(c - maskedPixel[k]) < 4), `under the mask the pixels stay: ${keep.map(Math.round)} vs ${maskedPixel.map(Math.round)}`);
  const [spotAfter, pastAfter] = [(await pick(spot)).t, (await pick(past)).t];
  assert.ok(Math.abs(spotAfter - spotDepth) < 0.05, `the masked surface stays put: ${spotDepth} -> ${spotAfter} vu from the eye`);
  assert.ok(pastDepth - pastAfter > 0.5, `past the mask the blob rises: ${pastDepth} -> ${pastAfter} vu from the eye`);

  // The whole-volume menu clears the mask.
  await page.locator("#global-op").selectOption("mask.clear");
  assert.equal(await page.locator("#global-amount-row").isVisible(), false, "mask operations take no amount");
  r = await revision(page);
  from = sent.length;
  await page.click("#global-apply");
  await changed(page, r);
  assert.ok(sent.slice(from).some((m) => m.method === "mask.clear"), "Clear the mask sends mask.clear");
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});

test("a painting collaborator's ring shows in the paint colour", { timeout: 180000 }, async () => {
  const errors = [];
  const a = await env.browser.context.newPage();
  collectErrors(a, errors);
  await createSession(a, 64, "sphere");
  const b = await env.browser.context.newPage();
  collectErrors(b, errors);
  await b.goto(await a.evaluate(() => location.href));
  await settled(b);
  await a.bringToFront();
  await a.click('label:has(input[value="paint"])');
  await a.locator("#paint-color").fill("#00ff00");
  const [x, y] = await canvasCenter(a);
  await a.mouse.move(x, y);
  await a.mouse.move(x + 2, y + 1);
  // b's view of a's ring: presence-rings.js turns the brush's colour into the ring's.
  await b.waitForFunction(() => {
    const others = [...window.marzipan.presence.board.others.values()];
    return others.some((o) => o.brush && Array.isArray(o.brush.color) && o.brush.color.join() === "0,255,0");
  }, null, { timeout: 20000 });
  assert.deepEqual(errors, [], "no script errors");
  await b.close();
  await a.close();
});
