// The web client end to end (as client.test.mjs): a whole-volume smoothing cancelled, the
// pig's front and the orthographic view in both views, and its snout close up, whose rim
// ripples less with normals varying across the discs than with flat ones (snout-ripple.json).
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { artifacts, changedPixels, collectErrors, createSession, data, drawn, env, modelFraction, RIPPLE_LIMIT, shot, useServerAndBrowser } from "./client-page.mjs";
import { revision } from "./harness.mjs";
import { backdropPixels, rimRipple } from "./rim.mjs";

useServerAndBrowser({ hintDismissed: true });

test("a whole-volume smoothing fills the progress bar and Cancel stops it, changing nothing; the pig's front and the orthographic view", { timeout: 180000 }, async (t) => {
  const errors = [];
  const page = await env.browser.context.newPage();
  collectErrors(page, errors);
  await createSession(page, 128, "pig");
  await page.selectOption("#global-op", "smooth");
  await page.locator("#global-amount").fill("1500");
  await page.click("#global-apply");
  // The bar is determinate once the server reports op.progress, and the Cancel button shows.
  await page.waitForFunction(() => document.querySelector("#progress progress").value > 0, null, { timeout: 60000 });
  assert.equal(await page.locator("#progress-cancel").isVisible(), true);
  await page.click("#progress-cancel");
  await page.waitForFunction(() => document.getElementById("progress").hidden, null, { timeout: 30000 });
  const history = await page.evaluate(() => window.marzipan.messages.history);
  assert.ok(history.some((m) => m.kind === "error" && m.text.includes("was cancelled") && m.detail.includes("-32016")), JSON.stringify(history));
  assert.equal(await data(page, "revision", "revision"), "0");

  // The pig faces +x: its link says so, and Front (key 1) looks at its face.
  assert.match(await page.evaluate(() => location.hash), /&front=%2Bx$/, "the link carries the pig's front");
  await page.locator("#view").focus();
  await page.keyboard.press("1");
  for (const close of await page.locator('.message button[aria-label="Dismiss"]').all()) await close.click();
  const back = await page.evaluate(() => window.marzipan.camera.backward);
  assert.ok(Math.abs(back[0] - 1) < 1e-9, `Front looks at the pig from +x: ${back}`);
  await page.mouse.move(5, 5);
  // Orthographic (key 5): the same framing through a 1.2 degree lens, in both views.
  const perspective = await shot(page, "12-pig-front");
  await page.keyboard.press("5");
  assert.equal(await page.locator("#orthographic").isChecked(), true);
  assert.equal(await page.evaluate(() => window.marzipan.camera.toProtocol().fov), 1.2);
  await page.waitForTimeout(300);
  await drawn(page);
  const ortho = await shot(page, "13-pig-front-orthographic");
  // The same with the discs drawn opaque, as before blending: scales on the body, beads on rims.
  await page.evaluate(() => {
    window.marzipan.renderer.splats.blend = false;
    window.marzipan.renderer.requestRedraw();
  });
  await page.waitForTimeout(400);
  await drawn(page);
  await shot(page, "13-pig-front-orthographic-opaque");
  // Blended with one flat normal per disc, as before the normals varied: beads on the rims.
  await page.evaluate(() => {
    window.marzipan.renderer.splats.blend = true;
    window.marzipan.store.setVaryNormals(false);
    window.marzipan.renderer.requestRedraw();
  });
  await page.waitForTimeout(400);
  await drawn(page);
  await shot(page, "13-pig-front-orthographic-flat-normals");
  await page.evaluate(() => {
    window.marzipan.store.setVaryNormals(true);
    window.marzipan.renderer.requestRedraw();
  });
  const [pf, of] = [modelFraction(perspective), modelFraction(ortho)];
  t.diagnostic(`model pixels: ${pf.toFixed(3)} perspective, ${of.toFixed(3)} orthographic`);
  assert.ok(Math.abs(of / pf - 1) < 0.2, "about the same framing");
  assert.ok(changedPixels(perspective, ortho) > 500, "but a different projection");
  await page.click('label:has(input[value="frames"])');
  await page.waitForFunction(() => Number(document.getElementById("stat-frame").dataset.received || 0) > 0, null, { timeout: 30000 });
  await page.waitForTimeout(600);
  await drawn(page);
  const frame = await shot(page, "14-pig-front-orthographic-frame");
  assert.ok(Math.abs(modelFraction(frame) / of - 1) < 0.1, `the server's frame frames it alike (${modelFraction(frame)} vs ${of})`);

  // The snout close up, face on: its rim is a bevel a voxel or two wide (engine/solids.cpp: a
  // cylinder of radius 0.055 N about (0.39 N, 0.08 N, 0) from the middle, its front cap at
  // 0.43 N). With one flat normal per disc the bevel's discs ripple round it as beads; with
  // varying normals it shades smoothly, as in the server's frame.
  await page.click('label:has(input[value="splats"])');
  const N = 128, mid = (N - 1) / 2;
  const snout = [mid + 0.43 * N, mid + 0.08 * N, mid];
  const onScreen = (p) =>
    page.evaluate((p) => {
      const m = window.marzipan.camera.viewProjection, c = document.getElementById("view");
      const x = m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12], y = m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13], w = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
      return [(x / w / 2 + 0.5) * c.clientWidth, (0.5 - y / w / 2) * c.clientHeight];
    }, p);
  const view = await page.locator("#view").boundingBox();
  const s0 = await onScreen(snout);
  await page.mouse.click(view.x + s0[0], view.y + s0[1], { button: "right", clickCount: 2 }); // centre on the snout
  await page.waitForTimeout(800);
  await page.mouse.move(view.x + view.width / 2, view.y + view.height / 2);
  await page.mouse.wheel(0, -400);
  await page.mouse.move(5, 5);
  await page.waitForTimeout(800);
  const [centre, top] = [await onScreen(snout), await onScreen([snout[0], snout[1] + 0.055 * N, snout[2]])];
  const radius = Math.hypot(top[0] - centre[0], top[1] - centre[1]);
  assert.ok(radius > 50 && centre.every((v, k) => v > 1.3 * radius && v < [view.width, view.height][k] - 1.3 * radius), `the snout fills the middle: ${centre}, radius ${radius} px`);
  const snoutVarying = await shot(page, "16-snout-close");
  await page.evaluate(() => {
    window.marzipan.store.setVaryNormals(false);
    window.marzipan.renderer.requestRedraw();
  });
  await page.waitForTimeout(400);
  await drawn(page);
  const snoutFlat = await shot(page, "16-snout-close-flat-normals");
  await page.evaluate(() => {
    window.marzipan.store.setVaryNormals(true);
    window.marzipan.renderer.requestRedraw();
  });
  await page.click('label:has(input[value="frames"])');
  await page.waitForFunction((n) => Number(document.getElementById("stat-frame").dataset.received || 0) > n, Number(await data(page, "stat-frame", "received")));
  await page.waitForTimeout(2000);
  await drawn(page);
  const snoutFrame = await shot(page, "16-snout-close-frame");
  const ripple = { varying: rimRipple(snoutVarying, centre, radius), flat: rimRipple(snoutFlat, centre, radius), frame: rimRipple(snoutFrame, centre, radius) };
  t.diagnostic(`snout rim ripple (RMS luminance about its mean over 7.5 degrees either side): ${JSON.stringify(ripple)}`);
  writeFileSync(join(artifacts, "snout-ripple.json"), `${JSON.stringify({ centre, radius, ripple }, null, 2)}\n`);
  assert.ok(ripple.varying < RIPPLE_LIMIT && ripple.flat > RIPPLE_LIMIT, `varying normals smooth the snout's rim: ${ripple.varying} vs ${ripple.flat} flat (limit ${RIPPLE_LIMIT})`);
  // Only the normals changed, not the discs: where the backdrop shows through (a few pixels
  // where the bevel's discs are seen edge on), it shows alike.
  const around = [centre[0] / view.width - 0.1, centre[1] / view.height - 0.1, centre[0] / view.width + 0.1, centre[1] / view.height + 0.1];
  assert.equal(backdropPixels(snoutVarying, around), backdropPixels(snoutFlat, around), "the same coverage");
  assert.deepEqual(errors, [], "no script errors");
  assert.deepEqual(await page.evaluate(() => window.marzipan.messages.history.filter((m) => m.kind === "error" && !m.text.includes("cancelled")).map((m) => m.text)), []);
  await page.close();
});
