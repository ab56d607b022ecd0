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

import { test } from "node:test";
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { digest, ensureArtifactsDir, LOW_DENSITY, revision, serverAndBrowser, settled } from "./harness.mjs";

const artifacts = ensureArtifactsDir();
// Its checks read the pages' state, never their pictures: LOW_DENSITY.
const env = serverAndBrowser({ deviceScaleFactor: LOW_DENSITY });
const clientId = (page) => page.evaluate(() => window.marzipan.session.info.client);
const errorsShown = (page) => page.evaluate(() => window.marzipan.messages.history.filter((m) => m.kind === "error").map((m) => m.text));


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

// Creates a 128³ sphere session on `page` as `name` (typed into the start screen); resolves with
// {link, viewLink}.
async function createSession(page, name) {
  await page.goto(`${env.server.url}/`);
  await page.fill("#your-name", name);
  await page.selectOption("#create-size", "128");
  await page.selectOption("#create-solid", "sphere");
  await page.click("#create-button");
  await settled(page);
  const link = await page.evaluate(() => location.href);
  const viewToken = await page.evaluate(() => window.marzipan.session.info.view_token);
  return { link, viewLink: link.replace(/token=[^&]+/, `token=${viewToken}`) };
}

// A new page that opens `link` as `name`: the pages share one browser profile, so the name this
// browser remembers (localStorage, ui/start-screen.js) is set before the page's scripts run.
async function openNamed(link, name) {
  const page = await env.browser.context.newPage();
  await page.addInitScript((n) => localStorage.setItem("marzipan.name", n), name);
  await page.goto(link);
  await settled(page);
  return page;
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
  const a = await env.browser.context.newPage();
  const sentA = recordSent(a);
  const { link } = await createSession(a, "Ada");
  const b = await openNamed(link, "Bea");
  for (const p of [a, b]) await p.waitForFunction(() => document.getElementById("clients").dataset.count === "2", null, { timeout: 30000 });
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
  await a.waitForFunction((n) => window.marzipan.messages.history.filter((m) => m.kind === "error").length > n, errorsBefore, { timeout: 30000 });
  const said = (await errorsShown(a)).at(-1);
  assert.equal(
    said,
    `Cannot undo your step at revision ${rA2}: Bea (client #${idB}) changed the same place at revision ${rB2}. Nothing changed; ask them to undo theirs first, or fork from the timeline.`,
  );
  await a.waitForSelector(`.message.error >> text=Bea (client #${idB}) changed the same place at revision ${rB2}`, { timeout: 30000 });
  writeFileSync(join(artifacts, "undo-conflict.png"), await a.screenshot());
  assert.equal(await revision(a), rB2, "the refused undo changed nothing");
  assert.equal(await digest(a), dConflict);

  // The timeline: every step with its author, in the history's order (A's first stroke, taken
  // out and put back by undo and redo mine, now comes after B's); hovering A's second stroke
  // previews the volume right after it.
  await a.click("#timeline-panel summary");
  await a.waitForFunction((r) => document.getElementById("timeline").dataset.revision === String(r), rB2, { timeout: 30000 });
  const rows = await a.$$eval("#timeline li", (lis) => lis.map((li) => [Number(li.dataset.revision), li.dataset.author]));
  assert.deepEqual(rows, [[rB2, "Bea"], [rA2, "you"], [rA, "you"], [rB, "Bea"]], "newest first, with the authors' names");
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
  await b.waitForFunction(() => document.getElementById("clients").dataset.count === "1", null, { timeout: 30000 });
  assert.equal(await digest(b), dConflict, "the old session is unchanged");
  // Alone in the fork, the page's undo is the session's again: nothing to undo in a fresh history.
  assert.equal(await a.evaluate(() => window.marzipan.session.undoScope), "session");
  assert.deepEqual(await errorsShown(b), [], "B saw no error");
  await a.close();
  await b.close();
});

// The rings another page draws: [{client, center, radius, active}] (ui/presence-view.js).
const ringsOn = (page) => page.evaluate(() => window.marzipan.presence.shown);
const hitOf = (page) => page.evaluate(() => window.marzipan.sculpt.hit && [...window.marzipan.sculpt.hit.point]);
const cameraOf = (page) => page.evaluate(() => window.marzipan.camera.toProtocol());
const peopleOn = (page) =>
  page.$$eval("#people-list li", (lis) => lis.map((li) => ({ client: Number(li.dataset.client), name: li.dataset.name, doing: li.dataset.doing, followed: li.dataset.followed === "true", you: li.classList.contains("you") })));

// Waits until `page` draws `client`'s ring at `point` (exactly: presence carries the sender's
// numbers as they are) with the given `active`.
async function ringAt(page, client, point, active) {
  await page
    .waitForFunction(
      ({ client, point, active }) =>
        window.marzipan.presence.shown.some((r) => r.client === client && r.active === active && r.center.every((v, k) => Math.abs(v - point[k]) < 1e-9)),
      { client, point, active },
      { timeout: 30000 },
    )
    .catch(async (e) => {
      throw new Error(`no ring of client ${client} at ${JSON.stringify(point)} (active ${active}); rings drawn ${JSON.stringify(await ringsOn(page))} (${e.message})`);
    });
}

// Waits until `follower`'s camera is `leader`'s (eye and target within 1e-6 vu, the same fov).
async function sameCamera(follower, leader) {
  const want = await cameraOf(leader);
  await follower
    .waitForFunction(
      (want) => {
        const c = window.marzipan.camera.toProtocol();
        const near = (a, b) => a.every((v, k) => Math.abs(v - b[k]) < 1e-6);
        return near(c.eye, want.eye) && near(c.target, want.target) && c.fov === want.fov;
      },
      want,
      { timeout: 30000 },
    )
    .catch(async (e) => {
      throw new Error(`camera ${JSON.stringify(await cameraOf(follower))} is not the leader's ${JSON.stringify(want)} (${e.message})`);
    });
}

// A right drag (an orbit anywhere) of `dx` pixels across the middle of the page's canvas.
async function orbit(page, dx) {
  const box = await page.locator("#view").boundingBox();
  const [x, y] = [box.x + box.width / 2, box.y + box.height / 2];
  await page.mouse.move(x, y);
  await page.mouse.down({ button: "right" });
  for (let i = 1; i <= 6; ++i) await page.mouse.move(x + (dx * i) / 6, y);
  await page.mouse.up({ button: "right" });
}

test("presence: rings move while a sculptor drags, the people list, following a camera until you orbit, a viewer follows too", { timeout: 300000 }, async () => {
  const a = await env.browser.context.newPage();
  const sentA = recordSent(a);
  const { link, viewLink } = await createSession(a, "Ada");
  const b = await openNamed(link, "Bea");
  const c = await openNamed(viewLink, "Cy");
  for (const p of [a, b, c]) await p.waitForFunction(() => document.getElementById("clients").dataset.count === "3", null, { timeout: 30000 });
  const [idA, idB, idC] = [await clientId(a), await clientId(b), await clientId(c)];
  const colourA = await a.evaluate(() => window.marzipan.session.clients.find((c) => c.client === window.marzipan.session.info.client).color);

  // The list: everyone with their name and colour, this page first; the viewer says so.
  await b.waitForSelector("#people:not([hidden])");
  let people = await peopleOn(b);
  assert.deepEqual(people.map((p) => [p.client, p.name, p.you]), [[idB, "Bea", true], [idA, "Ada", false], [idC, "Cy", false]]);
  assert.equal(people.find((p) => p.client === idC).doing, "view only");

  // A's pointer over the model: B draws A's ring exactly where A's brush is, and it moves with
  // A's pointer, with no edit at all (the revision stays).
  const r0 = await revision(b);
  const box = await a.locator("#view").boundingBox();
  const [cx, cy] = [box.x + box.width / 2, box.y + box.height / 2];
  await a.mouse.move(cx - 60, cy);
  const p1 = await hitOf(a);
  assert.ok(p1, "A's pointer is on the model");
  await ringAt(b, idA, p1, false);
  await a.mouse.move(cx - 20, cy - 40);
  const p2 = await hitOf(a);
  assert.notDeepEqual(p1, p2);
  await ringAt(b, idA, p2, false);
  await ringAt(c, idA, p2, false);
  assert.equal(await revision(b), r0, "the ring moved without any edit");
  await b.waitForFunction((id) => document.querySelector(`#people-list li[data-client="${id}"]`).dataset.doing === "add blob", idA, { timeout: 30000 });
  const presenceSent = sentA.filter((m) => m.method === "presence");
  assert.ok(presenceSent.length >= 2 && presenceSent.every((m) => m.id === undefined && m.params.camera), "presence goes out as notifications with the camera");

  // A drags: while A's button is down, B sees A's ring active at A's brush and following it.
  await a.mouse.down();
  for (let i = 1; i <= 4; ++i) await a.mouse.move(cx - 20, cy - 40 + 5 * i);
  const p3 = await hitOf(a);
  await ringAt(b, idA, p3, true);
  await b.waitForFunction((id) => document.querySelector(`#people-list li[data-client="${id}"]`).dataset.doing === "add blob · sculpting", idA, { timeout: 30000 });
  for (let i = 1; i <= 4; ++i) await a.mouse.move(cx - 20, cy - 20 + 5 * i);
  const p4 = await hitOf(a);
  assert.notDeepEqual(p3, p4);
  await ringAt(b, idA, p4, true);
  // A's dabs land meanwhile: B marks the region each changed, in A's colour, as it lands.
  await b.waitForFunction((id) => window.marzipan.presence.marked.some((m) => m.client === id), idA, { timeout: 20000 }).catch(async (e) => {
    throw new Error(`no mark on B: revisions A ${await revision(a)} B ${await revision(b)} (${e.message})`);
  });
  const marked = await b.evaluate(() => window.marzipan.presence.marked);
  assert.ok(marked.every((m) => m.client === idA && m.color === colourA), `marked in A's colour: ${JSON.stringify(marked)}`);
  await a.mouse.up();
  await settled(a);
  await ringAt(b, idA, await hitOf(a), false);

  // B's pointer on the model too: the viewer sees both sculptors' rings, each with its name.
  const boxB = await b.locator("#view").boundingBox();
  await b.mouse.move(boxB.x + boxB.width / 2 + 80, boxB.y + boxB.height / 2 + 30);
  await ringAt(c, idB, await hitOf(b), false);
  await c.waitForFunction(() => document.getElementById("view").dataset.rings === "2", null, { timeout: 30000 });
  const labels = await c.$$eval(".presence-label:not([hidden])", (els) => els.map((e) => e.textContent).sort());
  assert.deepEqual(labels, ["Ada", "Bea"]);
  assert.equal(await c.evaluate(() => window.marzipan.sculpt.presenceBrush), null, "a viewer has no brush to show");
  writeFileSync(join(artifacts, "presence-rings.png"), await c.screenshot());

  // B follows A: B's camera becomes A's, and stays A's while A orbits.
  await b.click(`#people-list li[data-client="${idA}"] button.follow`);
  await sameCamera(b, a);
  await b.waitForSelector("#follow-note >> text=Following Ada");
  await orbit(a, 120);
  await sameCamera(b, a);
  // The viewer follows A too.
  await c.click(`#people-list li[data-client="${idA}"] button.follow`);
  await orbit(a, -60);
  await sameCamera(b, a);
  await sameCamera(c, a);
  people = await peopleOn(c);
  assert.equal(people.find((p) => p.client === idA).followed, true);
  writeFileSync(join(artifacts, "people-list.png"), await c.locator("#people").screenshot());

  // B orbits: following stops, and says so; A's next orbit leaves B's camera where B put it.
  // The note shows for 6 s: wait for it from before the orbit, so that a loaded machine's slow
  // mouse moves cannot use up its time before the wait begins.
  const stoppedNote = b.waitForSelector("#follow-note >> text=Stopped following: you moved the camera.");
  await orbit(b, 80);
  await stoppedNote;
  assert.equal((await peopleOn(b)).find((p) => p.client === idA).followed, false);
  const mine = await cameraOf(b);
  await orbit(a, 100);
  await sameCamera(c, a);
  assert.deepEqual(await cameraOf(b), mine, "B no longer follows");

  // A leaves: its ring and its row go, and the viewer's following stops.
  await a.close();
  for (const p of [b, c]) await p.waitForFunction(() => document.getElementById("view").dataset.rings !== undefined && !window.marzipan.presence.shown.some((r) => r.client !== window.marzipan.session.info.client && window.marzipan.session.clients.every((c) => c.client !== r.client)), null, { timeout: 30000 });
  await c.waitForFunction((id) => !document.querySelector(`#people-list li[data-client="${id}"]`), idA, { timeout: 30000 });
  // The rings shown are those of the last frame drawn: under SwiftShader the next one may come
  // a while after the list changed.
  await c.waitForFunction((id) => !window.marzipan.presence.shown.some((r) => r.client === id), idA, { timeout: 30000 });
  assert.ok(!(await ringsOn(c)).some((r) => r.client === idA), "A's ring is gone");
  await c.waitForSelector("#follow-note >> text=Stopped following: they left the session.");
  assert.deepEqual(await errorsShown(b), [], "B saw no error");
  assert.deepEqual(await errorsShown(c), [], "C saw no error");
  await b.close();
  await c.close();
});
