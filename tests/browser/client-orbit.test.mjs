// The web client end to end (as client.test.mjs): orbiting and the stabiliser.
// What must hold: Space+drag orbits around the point under the press, which stays under it;
// the stabiliser lays a calmer path of dabs for a shaky drag.
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";

import { canvasCenter, collectErrors, createSession, drag, env, text, useServerAndBrowser } from "./client-page.mjs";
import { revision, settled } from "./harness.mjs";

useServerAndBrowser({ hintDismissed: true });

test("Space+drag orbits around the point under the press; the stabiliser calms a shaky drag", { timeout: 180000 }, async (t) => {
  const errors = [];
  const page = await env.browser.context.newPage();
  collectErrors(page, errors);
  const sent = [];
  page.on("websocket", (ws) => ws.on("framesent", (f) => typeof f.payload === "string" && sent.push(JSON.parse(f.payload))));
  const sentSince = (from, method) => sent.slice(from).filter((m) => m.method === method);
  await createSession(page, 128, "sphere");
  const [cx, cy] = await canvasCenter(page);
  await page.click('label:has(input[value="add_blob"])');
  const yaw = () => page.evaluate(() => window.marzipan.camera.yaw);
  const yaw0 = await yaw();
  const rOrbit = await revision(page);
  // The orbit turns around the surface point under the press, which stays where it was on screen.
  const [px, py] = [cx - 30, cy + 20];
  const pivot = await page.evaluate(([x, y]) => {
    const r = document.getElementById("view").getBoundingClientRect();
    return window.marzipan.sculpt.pick(x - r.left, y - r.top).point;
  }, [px, py]);
  await page.locator("#view").focus();
  await page.keyboard.down("Space");
  await drag(page, [px, py], [px + 60, py - 20], 6);
  await page.keyboard.up("Space");
  await page.waitForTimeout(300);
  assert.notEqual(await yaw(), yaw0, "Space+drag on the model orbits");
  assert.equal(await revision(page), rOrbit, "and does not sculpt");
  const pivotOnScreen = await page.evaluate((p) => {
    const c = document.getElementById("view");
    const r = c.getBoundingClientRect();
    const m = window.marzipan.camera.update(c.clientWidth, c.clientHeight).viewProjection; // column-major
    const clip = [0, 1, 2, 3].map((i) => m[i] * p[0] + m[4 + i] * p[1] + m[8 + i] * p[2] + m[12 + i]);
    return [r.left + ((clip[0] / clip[3] + 1) / 2) * c.clientWidth, r.top + ((1 - clip[1] / clip[3]) / 2) * c.clientHeight];
  }, pivot);
  assert.ok(Math.hypot(pivotOnScreen[0] - px, pivotOnScreen[1] - py) < 1.5, `the pivot stays under the press: ${pivotOnScreen} vs ${[px, py]}`);

  // The stabiliser: with a slack of 30 px the brush trails a shaky pointer on its string, so
  // the same zig-zag drag lays a shorter, calmer path of dabs.
  const zigzag = async () => {
    const from = sent.length;
    const r = await revision(page);
    await page.mouse.move(cx - 60, cy - 20);
    await page.mouse.down();
    for (let i = 1; i <= 40; ++i) await page.mouse.move(cx - 60 + 3 * i, cy - 20 + (i % 2 ? 6 : -6));
    await page.mouse.up();
    await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, r);
    await settled(page);
    return sentSince(from, "stroke.dabs").flatMap((m) => m.params.dabs).length;
  };
  await page.locator("#radius").fill("4");
  const plainDabs = await zigzag();
  await page.locator("#lazy").fill("30");
  assert.equal(await text(page, "lazy-value"), "30 px");
  const lazyDabs = await zigzag();
  await page.locator("#lazy").fill("0");
  t.diagnostic(`a shaky 120 px drag at radius 4: ${plainDabs} dabs, ${lazyDabs} with the stabiliser at 30 px`);
  assert.ok(lazyDabs >= 1 && lazyDabs < 0.8 * plainDabs, `the stabiliser calms the path: ${lazyDabs} dabs vs ${plainDabs}`);
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});
