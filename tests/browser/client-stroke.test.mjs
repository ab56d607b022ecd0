// The web client end to end (as client.test.mjs): a stroke's dabs land on the surface as it was
// at the press and a scrub grows at most the radius (stroke-growth.json); a groove close up is
// smoother blended than opaque, its rims straighter with varying normals (close-up-roughness.json);
// the grid's box shows when the model nears its faces.
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { artifacts, canvasCenter, data, drag, drawn, lowDensity, reach, RIM_LIMIT, roughness, scrub, sessionPage, shot, useServerAndBrowser } from "./client-page.mjs";
import { revision, settled } from "./harness.mjs";
import { backdropPixels, rimRoughness } from "./rim.mjs";

useServerAndBrowser({ hintDismissed: true });

test("a stroke's dabs land on the surface as it was at the press, and it stands at its height however often it passes", { timeout: 540000 }, async (t) => {
  const { page, errors, sent } = await sessionPage(128, "sphere"); // radius 0.35 * 128 = 44.8 vu about the grid's middle
  const center = [63.5, 63.5, 63.5];
  const r0 = await reach(page, center);
  assert.ok(Math.abs(r0 - 44.8) < 1, `the sphere's splats reach ${r0} vu`);
  const [cx, cy] = await canvasCenter(page);
  await page.locator("#radius").fill("8");
  // The scrubs and the groove read the splats, not the picture: at a sixteenth of the pixels
  // (LOW_DENSITY) until the close-up, whose pixels are measured at density 1.
  const fullDensity = await lowDensity(page);
  const strengths = [0.25, 0.5, 0.75, 1];
  const growth = { 1: {}, 12: {} }; // passes -> strength -> vu
  for (const passes of [1, 12])
    for (const strength of strengths) {
      await page.locator("#strength").fill(String(strength));
      const from = sent.length;
      const r = await revision(page);
      await scrub(page, [cx, cy], 20, passes);
      await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, r);
      await settled(page);
      growth[passes][strength] = (await reach(page, center)) - r0;
      const [begin] = sent.slice(from).filter((m) => m.method === "stroke.begin");
      assert.deepEqual(begin.params, { tool: "add_blob", radius: 8, strength, height: 4 * strength }, "a height, no build-up");
      const dabs = sent.slice(from).filter((m) => m.method === "stroke.dabs").flatMap((m) => m.params.dabs);
      assert.ok(dabs.length >= (passes === 1 ? 2 : 10) && dabs.every((d) => d.center && !d.ray), `the dabs go as centres picked on the client: ${dabs.length}, ${JSON.stringify(dabs.slice(0, 2))}`);
      // every dab lies on the sphere as it was before the stroke, never on the stroke's own growth
      const off = Math.max(...dabs.map((d) => Math.abs(Math.hypot(...d.center.map((v, k) => v - center[k])) - 44.8)));
      assert.ok(off < 1, `dabs within ${off.toFixed(2)} vu of the starting surface`);
      if (strength === 1 && passes === 12) await shot(page, "10-scrub-strength-1");
      const rStroke = await revision(page);
      await page.keyboard.press("Control+z");
      await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, rStroke);
      await settled(page);
    }
  t.diagnostic(`growth at radius 8 per strength (vu), 1 pass: ${JSON.stringify(growth[1])}, 12 passes: ${JSON.stringify(growth[12])}`);
  writeFileSync(join(artifacts, "stroke-growth.json"), `${JSON.stringify({ radius: 8, growth }, null, 2)}\n`);
  // The height is strength x 4 vu at radius 8: one pass and twelve stand alike, and a stronger
  // stroke stands higher.
  for (const s of strengths) {
    const [once, twelve] = [growth[1][s], growth[12][s]];
    assert.ok(Math.abs(twelve - once) <= 0.03 * once + 0.05, `strength ${s}: 1 pass ${once} vu, 12 passes ${twelve} vu`);
    assert.ok(Math.abs(once - 4 * s) <= 0.15 * 4 * s + 0.2, `strength ${s}: ${once} vu for a height of ${4 * s}`);
  }
  for (const p of [1, 12])
    for (let i = 1; i < strengths.length; ++i) assert.ok(growth[p][strengths[i]] > growth[p][strengths[i - 1]], `${p} passes: monotone in strength`);

  // A groove seen close up, blended and opaque: the discs' edges (fish scales) make the shading
  // jump from pixel to pixel where they are drawn opaque; blended, the surface is smooth.
  await page.click('label:has(input[value="remove_blob"])');
  await page.locator("#radius").fill("4");
  await page.locator("#strength").fill("1");
  const rGroove = await revision(page);
  await drag(page, [cx - 80, cy + 15], [cx + 80, cy - 15], 24);
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, rGroove);
  await settled(page);
  await fullDensity(); // the pictures from here on are measured
  await page.mouse.click(cx, cy, { button: "right", clickCount: 2 }); // centre the view on the groove
  await page.mouse.move(cx, cy);
  await page.mouse.wheel(0, -800); // zoom in towards it, to 0.3 of the distance
  await page.mouse.move(5, 5); // no brush cursor in the pictures
  await page.waitForTimeout(400);
  await drawn(page);
  const closeBlended = await shot(page, "15-groove-close-blended");
  // The same with one flat normal per disc, as before the normals varied across them.
  await page.evaluate(() => {
    window.marzipan.store.setVaryNormals(false);
    window.marzipan.renderer.requestRedraw();
  });
  await page.waitForTimeout(400);
  await drawn(page);
  const closeFlat = await shot(page, "15-groove-close-flat-normals");
  await page.evaluate(() => {
    window.marzipan.store.setVaryNormals(true);
    window.marzipan.renderer.splats.blend = false;
    window.marzipan.renderer.requestRedraw();
  });
  await page.waitForTimeout(400);
  await drawn(page);
  const closeOpaque = await shot(page, "15-groove-close-opaque");
  await page.evaluate(() => {
    window.marzipan.renderer.splats.blend = true;
    window.marzipan.renderer.requestRedraw();
  });
  const box = [0.1, 0.1, 0.9, 0.9];
  const close = await page.evaluate(() => {
    const c = document.getElementById("view");
    return { distance: window.marzipan.camera.distance, corners: [[0.1, 0.1], [0.9, 0.1], [0.1, 0.9], [0.9, 0.9]].every(([fx, fy]) => window.marzipan.sculpt.pick(fx * c.clientWidth, fy * c.clientHeight)) };
  });
  assert.ok(close.corners, `the model fills the close-up (distance ${close.distance})`);
  const [roughBlended, roughOpaque] = [roughness(closeBlended, box), roughness(closeOpaque, box)];
  t.diagnostic(`close-up roughness (mean |step| of luminance between neighbouring pixels): blended ${roughBlended.toFixed(2)}, opaque ${roughOpaque.toFixed(2)}`);
  assert.ok(roughBlended < 0.7 * roughOpaque, `blending smooths the close-up: ${roughBlended} vs ${roughOpaque} opaque`);
  // The rims: with one flat normal per disc each disc of a rim shows as a bead, whose round
  // outline turns the direction of the shading's edges from pixel to pixel; varying normals
  // shade the rim as one surface, its edges straight along it.
  const [rimVarying, rimFlat] = [rimRoughness(closeBlended, box), rimRoughness(closeFlat, box)];
  const [holesVarying, holesFlat] = [backdropPixels(closeBlended, box), backdropPixels(closeFlat, box)];
  t.diagnostic(`close-up rim roughness (1 - coherence of the edges' direction): varying normals ${rimVarying.toFixed(3)}, flat ${rimFlat.toFixed(3)}; backdrop pixels ${holesVarying}, ${holesFlat}`);
  writeFileSync(
    join(artifacts, "close-up-roughness.json"),
    `${JSON.stringify({ blended: roughBlended, opaque: roughOpaque, rim: { varying: rimVarying, flat: rimFlat }, backdropPixels: { varying: holesVarying, flat: holesFlat } }, null, 2)}\n`,
  );
  assert.ok(rimVarying < RIM_LIMIT && rimFlat > RIM_LIMIT, `varying normals smooth the rims: ${rimVarying} vs ${rimFlat} flat (limit ${RIM_LIMIT})`);
  assert.equal(holesVarying, 0, "no holes: the model covers the whole close-up");
  assert.equal(holesFlat, 0);
  const rGrooved = await revision(page);
  await page.keyboard.press("Control+z");
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, rGrooved);
  await settled(page);
  await page.keyboard.press("0");

  // Near the grid's faces the box shows, with a note; away from them neither does.
  assert.equal(await data(page, "view", "gridEdge"), "clear");
  assert.equal(await page.locator("#grid-note").isVisible(), false);
  const r = await revision(page);
  await page.evaluate(() => window.marzipan.session.applyTool({ tool: "csg_add", shape: "sphere", radius: 12, center: [118, 63.5, 63.5] }));
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, r);
  await settled(page);
  assert.equal(await data(page, "view", "gridEdge"), "near");
  assert.equal(await page.locator("#grid-note").isVisible(), true, "the note says the model nears the grid's edge");
  await shot(page, "11-grid-edge");
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});
