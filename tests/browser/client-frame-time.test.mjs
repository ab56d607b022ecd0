// The web client end to end (as client.test.mjs): the frame time of a 256^3 session holding a
// radius-100 sphere, blended, opaque and blended with flat normals (frame-time.json).
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { artifacts, collectErrors, createSession, data, env, shot, useServerAndBrowser } from "./client-page.mjs";
import { revision, settled } from "./harness.mjs";

useServerAndBrowser({ hintDismissed: true });

test("frame time of a 256^3 session with a radius-100 sphere", { timeout: 450000 }, async (t) => {
  const errors = [];
  const page = await env.browser.context.newPage();
  collectErrors(page, errors);
  await createSession(page, 256, "sphere"); // radius 0.35 * 256 = 89.6 vu
  await page.selectOption("#global-op", "dilate");
  await page.locator("#global-amount").fill("10.4");
  await page.click("#global-apply");
  await page.waitForFunction(() => document.getElementById("revision").dataset.revision === "1", null, { timeout: 120000 });
  await settled(page, 120000);
  const points = Number(await data(page, "stat-points", "points"));
  assert.ok(points > 150000 && points < 300000, `a radius-100 sphere has about 200k splats, got ${points}`);
  await shot(page, "09-sphere-256");
  await page.click("#stats-panel summary");
  await page.click("#measure-fps");
  await page.waitForFunction(() => document.getElementById("stat-frame-time").dataset.meanMs, null, { timeout: 240000 });
  const m = await page.evaluate(() => window.marzipan.lastMeasure);
  // The same orbit with the discs drawn opaque (no blending), for the cost of blending.
  const blended = await page.evaluate(() => window.marzipan.renderer.splats.blend);
  const opaque = await page.evaluate(async () => {
    const splats = window.marzipan.renderer.splats;
    splats.blend = false;
    const measured = await window.marzipan.renderer.measure();
    splats.blend = true;
    return measured;
  });
  // And blended with one flat normal per disc, as before the normals varied across them.
  const flat = await page.evaluate(async () => {
    window.marzipan.store.setVaryNormals(false);
    const measured = await window.marzipan.renderer.measure();
    window.marzipan.store.setVaryNormals(true);
    return measured;
  });
  t.diagnostic(`frame time, blended (${blended}): ${JSON.stringify(m)}; opaque: ${JSON.stringify(opaque)}; ratio ${(m.meanMs / opaque.meanMs).toFixed(2)}; flat normals: ${JSON.stringify(flat)}; varying / flat ${(m.meanMs / flat.meanMs).toFixed(2)}`);
  writeFileSync(join(artifacts, "frame-time.json"), `${JSON.stringify({ blended: m, opaque, flatNormals: flat }, null, 2)}\n`);
  assert.equal(blended, true, "Chromium's WebGL2 renders to half floats: the discs blend");
  assert.equal(m.points, points);
  assert.ok(m.meanMs > 0 && Number.isFinite(m.meanMs));
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});
