// The web client end to end (as client.test.mjs): orbiting and the stabiliser; the new tools.
// What must hold: Space+drag orbits around the point under the press, which stays under it;
// the stabiliser lays a calmer path of dabs for a shaky drag; then, each with a page and
// session of its own in the same browser (which saves a file's start-up): a grab takes a
// sphere's side where the pointer points, 30 vu out, and back to within 0.5 vu; a snake hook
// pulls the solid longer along the drag; a pinch path's dabs go on the surface and the flanks
// beside it sink; flatten takes a bump down towards the plane the server fitted, which the
// cursor shows.
// Conventions: pixel positions in CSS pixels of the page; screenshots, downloads and measures go
// to MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test } from "node:test";
import assert from "node:assert/strict";

import { canvasCenter, drag, LOW_DENSITY, sessionPage, shot, text, useServerAndBrowser } from "./client-page.mjs";
import { revision, settled } from "./harness.mjs";

// Its checks read the model and the camera, never the picture: LOW_DENSITY.
useServerAndBrowser({ hintDismissed: true, deviceScaleFactor: LOW_DENSITY });

test("Space+drag orbits around the point under the press; the stabiliser calms a shaky drag", { timeout: 180000 }, async (t) => {
  const { page, errors, sent } = await sessionPage(128, "sphere");
  const sentSince = (from, method) => sent.slice(from).filter((m) => m.method === method);
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

// --- the new tools (issue 29 §4), on a sphere of radius 0.35 * 128 = 44.8 vu about the grid's
// middle: a grab of its side 30 vu out and back, a snake hook, flatten on a bump ------------------

const CENTER = [63.5, 63.5, 63.5];
const R0 = 44.8;

// In the page: the surface point under a page pixel (the client's pick), a world point's page
// pixel, the camera's right axis.
const pickAt = (page, [x, y]) =>
  page.evaluate(([px, py]) => {
    const r = document.getElementById("view").getBoundingClientRect();
    const hit = window.marzipan.sculpt.pick(px - r.left, py - r.top);
    return hit && hit.point;
  }, [x, y]);
const pixelOf = (page, p) =>
  page.evaluate((q) => {
    const c = document.getElementById("view");
    const r = c.getBoundingClientRect();
    const m = window.marzipan.camera.update(c.clientWidth, c.clientHeight).viewProjection; // column-major
    const clip = [0, 1, 2, 3].map((i) => m[i] * q[0] + m[4 + i] * q[1] + m[8 + i] * q[2] + m[12 + i]);
    return [r.left + ((clip[0] / clip[3] + 1) / 2) * c.clientWidth, r.top + ((1 - clip[1] / clip[3]) / 2) * c.clientHeight];
  }, p);
// Every splat as [x, y, z] (the client's copy, current once settled()).
const splats = (page) =>
  page.evaluate(() => {
    const out = [];
    for (const b of window.marzipan.store.bricks.values()) for (let i = 0; i < 3 * b.count; i += 3) out.push([b.positions[i], b.positions[i + 1], b.positions[i + 2]]);
    return out;
  });
const sub = (a, b) => a.map((v, i) => v - b[i]);
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.hypot(...a);
const along = (a, k, d) => a.map((v, i) => v + k * d[i]);

// One drag of the selected tool from page pixel `from` through `to` in `steps` moves; resolves
// with the stroke's messages once the page has settled. `beforeRelease(page)` runs with the
// pointer still down at `to`.
async function strokeOf(page, sent, from, to, steps, beforeRelease = async () => {}) {
  const first = sent.length;
  const r = await revision(page);
  await page.mouse.move(from[0], from[1]);
  await page.mouse.down();
  for (let i = 1; i <= steps; ++i) await page.mouse.move(from[0] + ((to[0] - from[0]) * i) / steps, from[1] + ((to[1] - from[1]) * i) / steps);
  await beforeRelease(page);
  await page.mouse.up();
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, r);
  await settled(page);
  const mine = sent.slice(first);
  return {
    begin: mine.find((m) => m.method === "stroke.begin").params,
    messages: mine.filter((m) => m.method === "stroke.dabs").map((m) => m.params.dabs),
  };
}

test("warps in the page: grab a sphere's side 30 vu out and back, a snake hook pulls it longer", { timeout: 300000 }, async (t) => {
  const { page, errors, sent } = await sessionPage(128, "sphere");
  const before = await splats(page);
  const deviation = (points) => Math.max(...points.map((p) => Math.abs(norm(sub(p, CENTER)) - R0)));
  const dev0 = deviation(before);
  // The sphere leaves 19 vu to the grid's faces but 38 vu along its diagonals: the drags go in
  // the screen's plane towards a corner of the grid, (1, 1, -1) for the grab and (1, -1, 1)
  // for the snake hook (up and right, down, in the starting view).
  const backward = await page.evaluate(() => window.marzipan.camera.backward);
  const towards = (corner) => {
    const w = sub(corner, backward.map((v) => v * dot(corner, backward)));
    return w.map((v) => v / norm(w));
  };
  const inGrid = (p, what) => assert.ok(p.every((v) => v > 4 && v < 123), `${what} ${p.map((v) => v.toFixed(1))} lies well inside the grid`);
  const [ccx, ccy] = await pixelOf(page, CENTER);
  // the press: where the sphere's rim lies along w on screen, 0.8 of the way from its middle
  const pressAt = async (w) => {
    const [x, y] = await pixelOf(page, along(CENTER, R0, w));
    return [ccx + 0.8 * (x - ccx), ccy + 0.8 * (y - ccy)];
  };

  // Grab (key G): the press on the sphere's side, the pointer moved to where that point 30 vu
  // further out shows; the surface follows the anchor there.
  await page.keyboard.press("g");
  assert.equal(await page.evaluate(() => window.marzipan.controls.settings.tool), "grab", "G selects grab");
  await page.locator("#radius").fill("16");
  const w = towards([1, 1, -1]);
  const p0 = await pressAt(w);
  const anchor = await pickAt(page, p0);
  inGrid(along(anchor, 30, w), "the grab's target");
  const p1 = await pixelOf(page, along(anchor, 30, w));
  const out = await strokeOf(page, sent, p0, p1, 6, async () => {
    const cursor = await page.evaluate(() => ({ segments: window.marzipan.renderer.cursorShape.segments.length, readout: document.getElementById("brush-readout").textContent }));
    assert.equal(cursor.segments, 3, "the cursor shows an arrow from the anchor to the pointer");
    assert.match(cursor.readout, /Grab · (30\.\d|29\.9) vu/, "and says how far");
  });
  assert.equal(out.begin.tool, "grab");
  assert.equal(out.begin.strength, 1, "a warp's own strength, 1, whatever the brushes' (0.5)");
  for (const k of ["symmetry", "height", "accumulate", "direction"]) assert.ok(!(k in out.begin), `grab's stroke.begin has no ${k}: ${JSON.stringify(out.begin)}`);
  const dabs = out.messages.flat();
  assert.ok(norm(sub(dabs[0].center, anchor)) < 0.01, "the first dab is the anchor picked under the press");
  assert.ok(out.messages.length <= 7 && out.messages.slice(1).every((m) => m.length === 1), `only the newest point goes: ${out.messages.map((m) => m.length)}`);
  const target = dabs.at(-1).center;
  const moved = sub(target, dabs[0].center);
  assert.ok(Math.abs(norm(moved) - 30) < 0.3, `the pointer's point is 30 vu from the anchor: ${norm(moved)}`);
  assert.ok(Math.abs(dot(moved, backward)) < 1e-3, "on the plane facing the camera");
  const grabbed = await splats(page);
  const gap = Math.min(...grabbed.map((p) => norm(sub(p, target))));
  const reach = Math.max(...grabbed.map((p) => norm(sub(p, CENTER))));
  t.diagnostic(`grab 30 vu out: nearest splat to the pointer's point ${gap.toFixed(2)} vu, reach ${reach.toFixed(1)} vu (sphere ${R0})`);
  assert.ok(gap < 1.25, `the surface went where the pointer pointed: nearest splat ${gap} vu from it`);
  await shot(page, "17-grab-out");

  // And back: the press on the moved side, the pointer to where the anchor minus the move shows.
  const anchor2 = await pickAt(page, p1);
  const back1 = await pixelOf(page, sub(anchor2, moved));
  const backStroke = await strokeOf(page, sent, p1, back1, 6);
  const backDabs = backStroke.messages.flat();
  t.diagnostic(`grab back: anchor ${norm(sub(backDabs[0].center, target)).toFixed(2)} vu from where the first grab left it, moved ${norm(sub(backDabs.at(-1).center, backDabs[0].center)).toFixed(2)} vu`);
  const dev = deviation(await splats(page));
  t.diagnostic(`after out and back: every splat within ${dev.toFixed(3)} vu of the sphere (before: ${dev0.toFixed(3)})`);
  assert.ok(dev < 0.5 + dev0, `the sphere came back within 0.5 vu: ${dev} (before ${dev0})`);

  // Snake hook (key K): from another side, 40 vu further out in 12 moves; the solid gets
  // longer along the drag, its tip where the pointer ended.
  await page.keyboard.press("k");
  await page.locator("#radius").fill("10");
  const w2 = towards([1, -1, 1]);
  const extent = (points) => Math.max(...points.map((p) => dot(sub(p, CENTER), w2)));
  const extent0 = extent(await splats(page));
  const s0 = await pressAt(w2);
  const snakeAnchor = await pickAt(page, s0);
  inGrid(along(snakeAnchor, 40, w2), "the snake hook's end");
  const snakeEnd = await pixelOf(page, along(snakeAnchor, 40, w2));
  const snake = await strokeOf(page, sent, s0, snakeEnd, 12);
  const snakeDabs = snake.messages.flat();
  assert.ok(snakeDabs.length >= 10, `a path: its points go, spaced (${snakeDabs.length})`);
  const tip = dot(sub(snakeDabs.at(-1).center, CENTER), w2);
  const extent1 = extent(await splats(page));
  t.diagnostic(`snake hook 40 vu: the solid reaches ${extent1.toFixed(1)} vu along the drag (before ${extent0.toFixed(1)}, the pointer's last point ${tip.toFixed(1)}), ${snakeDabs.length} points in ${snake.messages.length} messages`);
  // the anchor sat 0.8 of the way out; the tip's surface reaches the pointer's last point
  assert.ok(extent1 >= tip - 1 && extent1 > extent0 + 20, `the solid got longer along the drag: ${extent0} -> ${extent1} (the pointer's last point ${tip})`);
  await shot(page, "18-snake-hook");

  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});

test("a pinch path in the page: its dabs go on the surface with pressure, and the flanks beside the path sink", { timeout: 180000 }, async (t) => {
  const { page, errors, sent } = await sessionPage(128, "sphere");
  const radial = (points) => points.map((p) => norm(sub(p, CENTER)) - R0);
  const before = radial(await splats(page));
  // Pinch path (key Q): a drag across the sphere's front, left to right.
  await page.keyboard.press("q");
  assert.equal(await page.evaluate(() => window.marzipan.controls.settings.tool), "pinch_path", "Q selects pinch path");
  await page.locator("#radius").fill("16");
  const [ccx, ccy] = await pixelOf(page, CENTER);
  const [rx] = await pixelOf(page, along(CENTER, R0, await page.evaluate(() => window.marzipan.camera.right)));
  const half = 0.5 * (rx - ccx);
  const out = await strokeOf(page, sent, [ccx - half, ccy], [ccx + half, ccy], 16);
  assert.equal(out.begin.tool, "pinch_path");
  assert.equal(out.begin.strength, 1, "a warp's own strength, 1, whatever the brushes' (0.5)");
  for (const k of ["symmetry", "height", "accumulate", "direction"]) assert.ok(!(k in out.begin), `pinch path's stroke.begin has no ${k}: ${JSON.stringify(out.begin)}`);
  const dabs = out.messages.flat();
  assert.ok(dabs.length >= 8, `a path of spaced dabs: ${dabs.length}`);
  const off = Math.max(...dabs.map((d) => Math.abs(norm(sub(d.center, CENTER)) - R0)));
  assert.ok(off < 1, `every dab on the surface as the stroke began: within ${off.toFixed(2)} vu`);
  assert.ok(dabs.slice(1).every((d) => typeof d.pressure === "number"), "with pressure");
  // The surface beside the path is drawn towards it, across: on a sphere its flanks sink
  // below the sphere, and nothing rises above it.
  const after = radial(await splats(page));
  const sunk = -Math.min(...after), rose = Math.max(...after) - Math.max(...before);
  t.diagnostic(`pinch path: ${dabs.length} dabs in ${out.messages.length} messages; the flanks sank ${sunk.toFixed(2)} vu, the most a splat rose ${rose.toFixed(2)} vu`);
  assert.ok(sunk > 0.3, `the flanks sank: ${sunk}`);
  assert.ok(rose < 0.3, `nothing rose: ${rose}`);
  await shot(page, "19-pinch-path");
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});

test("flatten in the page takes a bump down, towards the plane the server fitted, which the cursor shows", { timeout: 240000 }, async (t) => {
  const { page, errors, sent } = await sessionPage(128, "sphere");
  const right = await page.evaluate(() => window.marzipan.camera.right);
  const [ccx, ccy] = await pixelOf(page, CENTER);
  const [rx] = await pixelOf(page, along(CENTER, R0, right));
  const rPx = rx - ccx;
  // A bump that add blob raised at the front, then flatten (key B) over it: the bump's height drops.
  await page.keyboard.press("a");
  await page.locator("#radius").fill("8");
  await page.locator("#strength").fill("1");
  const front = [ccx, ccy - 0.3 * rPx];
  const bumpAt = await pickAt(page, front);
  const u = sub(bumpAt, CENTER).map((v) => v / norm(sub(bumpAt, CENTER)));
  const bump = (points) => Math.max(...points.filter((p) => dot(sub(p, CENTER), u) > 0.95 * norm(sub(p, CENTER))).map((p) => norm(sub(p, CENTER)))) - R0;
  await strokeOf(page, sent, [front[0] - 10, front[1]], [front[0] + 10, front[1]], 4);
  const raised = bump(await splats(page));
  await page.keyboard.press("b");
  await page.locator("#radius").fill("12");
  const r = await revision(page);
  // pressed on the bump (the plane is fitted within the radius of the first dab), then two
  // passes over it
  await page.mouse.move(front[0], front[1]);
  await page.mouse.down();
  for (let i = 1; i <= 4; ++i) await page.mouse.move(front[0] + 4 * i, front[1]);
  await page.waitForFunction(() => Boolean(window.marzipan.sculpt.stroke && window.marzipan.sculpt.stroke.sender.plane), null, { timeout: 30000 });
  const disc = await page.evaluate(() => window.marzipan.renderer.cursorShape.rings.filter((x) => x.width === 12).length);
  assert.equal(disc, 1, "the cursor shows the fitted plane as a disc of the radius");
  for (const [a, b] of [[16, -16], [-16, 16], [16, 0]]) for (let i = 1; i <= 8; ++i) await page.mouse.move(front[0] + a + ((b - a) * i) / 8, front[1]);
  await page.mouse.up();
  await page.waitForFunction((v) => Number(document.getElementById("revision").dataset.revision) > v, r);
  await settled(page);
  const flattened = bump(await splats(page));
  t.diagnostic(`flatten: the bump stood ${raised.toFixed(2)} vu, after flatten ${flattened.toFixed(2)} vu`);
  assert.ok(raised > 3, `add blob raised a bump: ${raised} vu`);
  assert.ok(flattened < 0.5 * raised, `flatten took the bump down: ${raised} -> ${flattened} vu`);
  await shot(page, "19-flatten");
  assert.deepEqual(errors, [], "no script errors");
  await page.close();
});
