// Two sculptors on one session in headless Chromium (issue 14: undo mine, the timeline, forks).
// What must hold: with two editors in the session each page's Undo (button and Ctrl+Z) sends
// history.undo with scope "mine" and takes back only that page's stroke (the other's stays:
// undoing both gives exactly the digest of before either, redoing gives exactly the digest of
// after both); an undo whose step a later stroke of the other page overlaps is refused and the
// page says who and which revision is in the way, changing nothing; the timeline lists the
// steps with their authors, previews a step's revision from history, and "Fork from here" opens
// a new session at that revision with that revision's digest.
// Conventions: pixel positions in CSS pixels of the page; screenshots go to
// MARZIPAN_BROWSER_ARTIFACTS (tests/browser/harness.mjs).

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { ensureArtifactsDir, startBrowser, startServer } from "./harness.mjs";

const artifacts = ensureArtifactsDir();
let server;
let browser;

before(async () => {
  server = await startServer();
  browser = await startBrowser();
});

after(async () => {
  if (browser) await browser.close();
  if (server) {
    const { code, signal } = await server.close();
    assert.equal(code, 0, `marzipan serve exited with ${code} (${signal}); its log:\n${server.log()}`);
  }
});

const revision = async (page) => Number(await page.evaluate(() => document.getElementById("revision").dataset.revision));
const digest = (page) => page.locator("#stat-digest").textContent();
const clientId = (page) => page.evaluate(() => window.marzipan.session.info.client);
const errorsShown = (page) => page.evaluate(() => window.marzipan.messages.history.filter((m) => m.kind === "error").map((m) => m.text));

// Connected, the splats shown are the session's revision's, no stroke on the wire.
async function settled(page, timeout = 60000) {
  await page.waitForFunction(
    () => {
      const $ = (id) => document.getElementById(id);
      const rev = $("revision").dataset.revision;
      return (
        $("connection").dataset.state === "connected" &&
        Number($("stat-points").dataset.points || 0) > 0 &&
        $("stat-points").dataset.revision === rev &&
        ($("view").dataset.strokes || "0") === "0"
      );
    },
    null,
    { timeout },
  );
  await page.waitForTimeout(150);
}

// Both pages at the same revision (each sees the other's edits) and settled.
async function bothAt(a, b, rev) {
  for (const p of [a, b])
    await p.waitForFunction((r) => Number(document.getElementById("revision").dataset.revision) === r, rev, { timeout: 30000 }).catch(async (e) => {
      throw new Error(`waiting for revision ${rev}: the page is at ${await revision(p)}, its errors ${JSON.stringify(await errorsShown(p))} (${e.message})`);
    });
  for (const p of [a, b]) await settled(p);
}

async function drag(page, from, to, steps = 12) {
  await page.mouse.move(from[0], from[1]);
  await page.mouse.down();
  for (let i = 1; i <= steps; ++i) await page.mouse.move(from[0] + ((to[0] - from[0]) * i) / steps, from[1] + ((to[1] - from[1]) * i) / steps);
  await page.mouse.up();
}

// A short vertical stroke at (cx + dx, cy) of the canvas; resolves with the page's revision
// once the stroke has ended and the page is settled.
async function stroke(page, dx) {
  const box = await page.locator("#view").boundingBox();
  const [x, y] = [box.x + box.width / 2 + dx, box.y + box.height / 2];
  await drag(page, [x, y - 30], [x, y + 30]);
  await settled(page);
  return revision(page);
}

// Every text message a page sends, parsed.
function recordSent(page) {
  const sent = [];
  page.on("websocket", (ws) =>
    ws.on("framesent", (f) => {
      if (typeof f.payload === "string") sent.push(JSON.parse(f.payload));
    }),
  );
  return sent;
}

test("two sculptors: undo mine leaves the other's stroke, a conflict is named, the timeline forks at a revision", { timeout: 300000 }, async () => {
  const a = await browser.context.newPage();
  const sentA = recordSent(a);
  await a.goto(`${server.url}/`);
  await a.selectOption("#create-size", "128");
  await a.selectOption("#create-solid", "sphere");
  await a.click("#create-button");
  await settled(a);
  const link = await a.evaluate(() => location.href);
  const b = await browser.context.newPage();
  await b.goto(link);
  await settled(b);
  for (const p of [a, b]) await p.waitForFunction(() => document.getElementById("clients").dataset.count === "2", null, { timeout: 10000 });
  const [idA, idB] = [await clientId(a), await clientId(b)];
  assert.notEqual(idA, idB);
  const d0 = await digest(a);
  const r0 = await revision(a);

  // A strokes on the left, B on the right, far apart (about 60 vu on the 128³ sphere), with a
  // small brush, so that no brick of one stroke's region is the other's.
  for (const p of [a, b]) await p.evaluate(() => window.marzipan.controls.setRadius(4));
  const rA = await stroke(a, -210);
  await bothAt(a, b, rA);
  const dA = await digest(a);
  const rB = await stroke(b, 210);
  await bothAt(a, b, rB);
  const dAB = await digest(a);
  assert.ok(r0 < rA && rA < rB, `revisions ${r0} < ${rA} < ${rB}`);
  assert.equal(new Set([d0, dA, dAB]).size, 3, "each stroke changed the volume");

  // A's Undo button takes back A's stroke only.
  const undosBefore = sentA.filter((m) => m.method === "history.undo").length;
  await a.click("#undo");
  await bothAt(a, b, rB + 1).catch(async (e) => {
    const regions = (await a.evaluate(() => window.marzipan.session.historyList())).steps.map((s) => [s.revision, s.region]);
    throw new Error(`${e.message}; steps' regions ${JSON.stringify(regions)}`);
  });
  const undos = sentA.filter((m) => m.method === "history.undo");
  assert.equal(undos.length, undosBefore + 1);
  assert.deepEqual(undos.at(-1).params, { scope: "mine" }, "with another editor in, the page undoes its own step");
  const dB = await digest(a);
  assert.equal(await digest(b), dB);
  assert.ok(dB !== dAB && dB !== d0 && dB !== dA, "A's stroke is gone and B's stays");
  const steps = await a.evaluate(() => window.marzipan.session.historyList());
  const byRev = new Map(steps.steps.map((s) => [s.revision, s]));
  assert.equal(byRev.get(rA).client, idA);
  assert.equal(byRev.get(rA).undone, true, "A's step is on the redo list");
  assert.equal(byRev.get(rB).client, idB);
  assert.equal(byRev.get(rB).undone, false, "B's step is not");
  // B's own undo (Ctrl+Z) then leaves exactly the volume of before both strokes, and the two
  // redos (mine) exactly the volume after both: the steps were taken out and put back whole.
  await b.focus("#view");
  await b.keyboard.press("Control+z");
  await bothAt(a, b, rB + 2);
  assert.equal(await digest(b), d0, "undoing both strokes restores the digest of before either");
  await b.keyboard.press("Control+Shift+z");
  await bothAt(a, b, rB + 3);
  assert.equal(await digest(a), dB);
  await a.click("#redo");
  await bothAt(a, b, rB + 4);
  assert.equal(await digest(a), dAB, "redoing both gives the digest of after both");

  // A conflict: A strokes in the middle, then B over the same place; A's undo is refused.
  const rA2 = await stroke(a, 0);
  await bothAt(a, b, rA2);
  const dA2 = await digest(a);
  const rB2 = await stroke(b, 0);
  await bothAt(a, b, rB2);
  const dConflict = await digest(a);
  const errorsBefore = (await errorsShown(a)).length;
  await a.focus("#view");
  await a.keyboard.press("Control+z");
  await a.waitForFunction((n) => window.marzipan.messages.history.filter((m) => m.kind === "error").length > n, errorsBefore, { timeout: 10000 });
  const said = (await errorsShown(a)).at(-1);
  assert.equal(
    said,
    `Cannot undo your step at revision ${rA2}: client #${idB} changed the same place at revision ${rB2}. Nothing changed; ask them to undo theirs first, or fork from the timeline.`,
  );
  await a.waitForSelector(`.message.error >> text=client #${idB} changed the same place at revision ${rB2}`, { timeout: 5000 });
  writeFileSync(join(artifacts, "undo-conflict.png"), await a.screenshot());
  assert.equal(await revision(a), rB2, "the refused undo changed nothing");
  assert.equal(await digest(a), dConflict);

  // The timeline: every step with its author, in the history's order (A's first stroke, taken
  // out and put back by undo and redo mine, now comes after B's); hovering A's second stroke
  // previews the volume right after it.
  await a.click("#timeline-panel summary");
  await a.waitForFunction((r) => document.getElementById("timeline").dataset.revision === String(r), rB2, { timeout: 10000 });
  const rows = await a.$$eval("#timeline li", (lis) => lis.map((li) => [Number(li.dataset.revision), li.dataset.author]));
  assert.deepEqual(rows, [[rB2, `#${idB}`], [rA2, "you"], [rA, "you"], [rB, `#${idB}`]], "newest first, with authors");
  const row = a.locator(`#timeline li[data-revision="${rA2}"]`);
  await a.locator("#timeline-panel").scrollIntoViewIfNeeded(); // the screenshot below scrolls no more
  await row.hover();
  await a.waitForFunction((r) => document.getElementById("timeline-preview-image").dataset.revision === String(r), rA2, { timeout: 30000 });
  assert.equal(await a.evaluate(() => document.getElementById("timeline-preview-image").naturalWidth), 192);
  writeFileSync(join(artifacts, "timeline.png"), await a.locator("#timeline-panel").screenshot());

  // Fork from A's second stroke: the page opens a new session at that revision, whose digest
  // is the one the session had then (before B's stroke over it); B stays in the old session,
  // now alone.
  const oldSession = await a.evaluate(() => window.marzipan.session.info.session);
  await row.locator("button.fork").click();
  await a.waitForFunction((s) => window.marzipan.session.info.session !== s, oldSession, { timeout: 30000 });
  await settled(a);
  const fork = await a.evaluate(() => ({ info: window.marzipan.session.info, hash: location.hash }));
  assert.deepEqual(fork.info.forked_from, { session: oldSession, revision: rA2 });
  assert.equal(fork.info.revision, rA2);
  assert.equal(await revision(a), rA2, "the fork starts at the chosen revision");
  assert.equal(await digest(a), dA2, "with the volume the session had at that revision");
  assert.ok(fork.hash.startsWith(`#session=${fork.info.session}&token=${fork.info.token}`), `the page's link is the fork's: ${fork.hash}`);
  await b.waitForFunction(() => document.getElementById("clients").dataset.count === "1", null, { timeout: 10000 });
  assert.equal(await digest(b), dConflict, "the old session is unchanged");
  // Alone in the fork, the page's undo is the session's again: nothing to undo in a fresh history.
  assert.equal(await a.evaluate(() => window.marzipan.session.undoScope), "session");
  assert.deepEqual(await errorsShown(b), [], "B saw no error");
  await a.close();
  await b.close();
});
