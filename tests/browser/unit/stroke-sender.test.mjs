// web-client/net/stroke-sender.js: what stroke.begin asks for, and when dabs go on the wire
// (brushes, anchored and path warps) and where the plane of flatten and contrast comes from.
import { test } from "node:test";
import assert from "node:assert/strict";

import { dabsOf, HEIGHT_PER_RADIUS, MAX_HEIGHT, StrokeSender, strokeBeginParams } from "../../../web-client/net/stroke-sender.js";
import { PARAMETERS, TOOLS } from "../../../protocol/js/tools.js";

test("add and remove blob strokes stand at strength times half the radius, without build-up", () => {
  assert.deepEqual(strokeBeginParams({ tool: "add_blob", radius: 8, strength: 1, symmetry: [] }), { tool: "add_blob", radius: 8, strength: 1, height: 4 });
  assert.deepEqual(strokeBeginParams({ tool: "remove_blob", radius: 12, strength: 0.25, symmetry: ["x"] }), {
    tool: "remove_blob",
    radius: 12,
    strength: 0.25,
    symmetry: ["x"],
    height: 1.5,
  });
  // monotone in strength and radius
  const h = (radius, strength) => strokeBeginParams({ tool: "add_blob", radius, strength }).height;
  for (const r of [0.5, 3, 8, 14.5, 40])
    for (const s of [0.05, 0.3, 0.55, 0.8]) {
      assert.ok(h(r, s + 0.2) > h(r, s), `r ${r}, strength ${s}`);
      assert.ok(h(r * 1.2, s) >= h(r, s), `r ${r}, strength ${s}`);
    }
});

test("the height never exceeds what the server takes (half the radius) nor the cap", () => {
  assert.equal(HEIGHT_PER_RADIUS, 0.5);
  for (const radius of [0.5, 1, 8.333, 14.4, 17.28, 33.3333, 64, 1024])
    for (const strength of [0.05, 0.35, 1]) {
      const { height } = strokeBeginParams({ tool: "add_blob", radius, strength });
      assert.ok(height > 0 && height <= radius / 2 && height <= MAX_HEIGHT, `radius ${radius}, strength ${strength}: ${height}`);
    }
  assert.equal(strokeBeginParams({ tool: "add_blob", radius: 200, strength: 1 }).height, MAX_HEIGHT);
});

test("build-up strokes and smoothing accumulate and carry no height", () => {
  assert.deepEqual(strokeBeginParams({ tool: "add_blob", radius: 8, strength: 1, buildUp: true }), { tool: "add_blob", radius: 8, strength: 1, accumulate: true });
  for (const tool of ["smooth", "sharpen"])
    for (const buildUp of [false, true])
      assert.deepEqual(strokeBeginParams({ tool, radius: 6, strength: 0.5, buildUp }), { tool, radius: 6, strength: 0.5, accumulate: true });
});

// --- warps and planes: what goes on the wire, against a session that records each request and
// answers when the test says (its answers are the protocol's shapes) ----------------------------


// Tools as the registry lists them (protocol/js/tools.js), for the warp kinds of the contract.
const param = (key) => PARAMETERS[key] || { key };
const WARPS = [
  { name: "grab", kind: "warp", dabs: "anchored", params: ["center", "radius", "strength"].map(param) },
  { name: "snake_hook", kind: "warp", dabs: "path", params: ["center", "radius", "strength"].map(param) },
  { name: "twist", kind: "warp", dabs: "anchored", params: ["center", "radius", "strength", "direction"].map(param) },
];
const TOOLS_WITH_WARPS = [...TOOLS, ...WARPS];

// The paint tools of the contract (PROTOCOL.md, stroke.begin): paint takes a colour, mask erase.
const PAINTS = [
  { name: "paint", kind: "paint", dabs: "swept", params: ["center", "radius", "strength", "color", "hardness"].map(param) },
  { name: "mask", kind: "paint", dabs: "swept", params: ["center", "radius", "strength", "hardness", "erase"].map(param) },
];
const TOOLS_WITH_PAINTS = [...TOOLS, ...PAINTS];

test("paint sends its colour, mask erase while inverted; both stand unless built up", () => {
  const settings = { radius: 6, strength: 0.5, symmetry: ["x"], color: [200, 20, 10] };
  assert.deepEqual(strokeBeginParams({ tool: "paint", ...settings }, TOOLS_WITH_PAINTS), {
    tool: "paint",
    radius: 6,
    strength: 0.5,
    color: [200, 20, 10],
    symmetry: ["x"],
  });
  assert.deepEqual(strokeBeginParams({ tool: "paint", ...settings, buildUp: true }, TOOLS_WITH_PAINTS).accumulate, true);
  assert.deepEqual(strokeBeginParams({ tool: "mask", ...settings }, TOOLS_WITH_PAINTS), { tool: "mask", radius: 6, strength: 0.5, symmetry: ["x"] });
  assert.deepEqual(strokeBeginParams({ tool: "mask", ...settings, erase: true }, TOOLS_WITH_PAINTS), {
    tool: "mask",
    radius: 6,
    strength: 0.5,
    erase: true,
    symmetry: ["x"],
  });
  // Other tools take neither.
  const blob = strokeBeginParams({ tool: "add_blob", ...settings, erase: true }, TOOLS_WITH_PAINTS);
  assert.equal("color" in blob || "erase" in blob, false);
});

class RecordingSession {
  constructor() {
    this.sent = []; // [method, params]
    this.pending = []; // answers to give, in order: {resolve, reject}
  }
  #ask(method, params) {
    this.sent.push([method, params]);
    return new Promise((resolve, reject) => this.pending.push({ method, resolve, reject }));
  }
  beginStroke(params) {
    return this.#ask("stroke.begin", params);
  }
  strokeDabs(stroke, dabs) {
    return this.#ask("stroke.dabs", { stroke, dabs });
  }
  endStroke(stroke) {
    return this.#ask("stroke.end", { stroke });
  }
  // Answers the oldest unanswered request with `result`, then lets the sender react.
  async answer(result) {
    const next = this.pending.shift();
    assert.ok(next, "a request to answer");
    next.resolve(result);
    await new Promise((r) => setTimeout(r, 0));
    return next.method;
  }
  dabMessages() {
    return this.sent.filter(([m]) => m === "stroke.dabs").map(([, p]) => p.dabs);
  }
}

const c = (x) => ({ center: [x, 0, 0] });

test("warps send no symmetry, height nor build-up; twist, scale and pinch their direction", () => {
  assert.deepEqual(strokeBeginParams({ tool: "grab", radius: 10, strength: 1, symmetry: ["x"], direction: [1, 0, 0] }, TOOLS_WITH_WARPS), { tool: "grab", radius: 10, strength: 1 });
  assert.deepEqual(strokeBeginParams({ tool: "twist", radius: 10, strength: 0.5, symmetry: ["x", "z"], buildUp: true, direction: [0, 0, -1] }, TOOLS_WITH_WARPS), {
    tool: "twist",
    radius: 10,
    strength: 0.5,
    direction: [0, 0, -1],
  });
  assert.equal(dabsOf("snake_hook", TOOLS_WITH_WARPS), "path");
  assert.equal(dabsOf("add_blob", TOOLS_WITH_WARPS), "swept");
  // the registry's own warps, once it has them
  for (const t of TOOLS.filter((x) => x.kind === "warp")) {
    const params = strokeBeginParams({ tool: t.name, radius: 8, strength: 1, symmetry: ["x"], direction: [0, 1, 0] });
    assert.equal(params.symmetry, undefined, t.name);
    assert.equal(params.height, undefined, t.name);
    assert.equal(params.accumulate, undefined, t.name);
    assert.equal("direction" in params, t.params.some((p) => p.key === "direction"), t.name);
  }
});

test("an anchored warp: the anchor first, then only the newest point, one message in flight and at most one per display frame", async () => {
  const session = new RecordingSession();
  const sender = new StrokeSender(session, { tool: "grab", radius: 10, strength: 1 }, 256, TOOLS_WITH_WARPS);
  sender.add(c(0)); // the anchor
  sender.add(c(1));
  sender.add(c(2)); // replaces 1: the anchor stays, since it has not gone yet
  assert.equal(await session.answer({ stroke: 7 }), "stroke.begin");
  assert.deepEqual(session.dabMessages(), [[c(0), c(2)]], "the begin's answer sends the anchor and the newest point");
  sender.add(c(3));
  sender.add(c(4));
  sender.flush(); // a display frame while the message is unanswered: it waits
  assert.equal(session.dabMessages().length, 1, "one message in flight");
  sender.add(c(5));
  await session.answer({ revision: 2, applied: 2, roi: null });
  assert.equal(session.dabMessages().length, 2, "the answer sends again, as no message went since the last frame");
  assert.deepEqual(session.dabMessages()[1], [c(5)], "only the newest point");
  sender.add(c(6));
  await session.answer({ revision: 3, applied: 1, roi: null });
  assert.equal(session.dabMessages().length, 2, "a message already went in this frame: the next waits for the frame");
  sender.add(c(7));
  sender.flush();
  assert.deepEqual(session.dabMessages()[2], [c(7)]);
  const done = sender.end();
  await session.answer({ revision: 4, applied: 1, roi: null });
  assert.deepEqual(session.sent.at(-1), ["stroke.end", { stroke: 7 }]);
  await session.answer({ revision: 4, can_undo: true, can_redo: false });
  await done;
  assert.equal(sender.applied, 4);
});

test("a path warp sends every point, up to three messages in flight, one per display frame", async () => {
  const session = new RecordingSession();
  const sender = new StrokeSender(session, { tool: "snake_hook", radius: 10, strength: 1 }, 256, TOOLS_WITH_WARPS);
  for (const x of [0, 1, 2]) sender.add(c(x));
  await session.answer({ stroke: 3 });
  sender.add(c(3));
  sender.flush();
  sender.add(c(4));
  sender.add(c(5));
  sender.flush();
  sender.add(c(6));
  sender.flush();
  sender.flush(); // a frame with nothing new
  assert.deepEqual(session.dabMessages(), [[c(0), c(1), c(2)], [c(3)], [c(4), c(5)]], "three in flight");
  await session.answer({ revision: 2, applied: 3, roi: null });
  assert.deepEqual(session.dabMessages().at(-1), [c(6)], "then the rest, every point");
  // the last point added after the pointer's release still goes, although no frame flushes an ended stroke
  sender.add(c(7));
  sender.end();
  for (let i = 0; i < 4; ++i) await session.answer({ revision: 3 + i, applied: 1, roi: null });
  assert.deepEqual(session.dabMessages().flat(), [0, 1, 2, 3, 4, 5, 6, 7].map(c));
  assert.deepEqual(session.sent.at(-1), ["stroke.end", { stroke: 3 }]);
});

test("a brush stroke is as before: every dab, no frame gate on answers", async () => {
  const session = new RecordingSession();
  const sender = new StrokeSender(session, { tool: "add_blob", radius: 8, strength: 1 }, 2);
  for (const x of [0, 1, 2, 3, 4]) sender.add(c(x));
  await session.answer({ stroke: 1 });
  assert.deepEqual(session.dabMessages(), [[c(0), c(1)], [c(2), c(3)], [c(4)]], "max_dabs a message, three in flight at once");
});

test("the plane of flatten and contrast is taken from stroke.begin's result or from the first stroke.dabs result that has one", async () => {
  const plane = { point: [1, 2, 3], normal: [0, 1, 0] };
  for (const where of ["begin", "dabs"]) {
    const session = new RecordingSession();
    const sender = new StrokeSender(session, { tool: "smooth", radius: 8, strength: 1 });
    const seen = [];
    sender.onPlane = (p) => seen.push(p);
    sender.add(c(0));
    await session.answer(where === "begin" ? { stroke: 2, plane } : { stroke: 2 });
    await session.answer(where === "dabs" ? { revision: 2, applied: 1, roi: null, plane } : { revision: 2, applied: 1, roi: null });
    sender.add(c(1));
    sender.flush();
    await session.answer({ revision: 3, applied: 1, roi: null, plane: { point: [9, 9, 9], normal: [1, 0, 0] } });
    assert.deepEqual(sender.plane, plane, `${where}: the first plane stays`);
    assert.deepEqual(seen, [plane], `${where}: announced once`);
  }
  const session = new RecordingSession();
  const sender = new StrokeSender(session, { tool: "smooth", radius: 8, strength: 1 });
  sender.add(c(0));
  await session.answer({ stroke: 2 });
  await session.answer({ revision: 2, applied: 1, roi: null, plane: { point: "here" } });
  assert.equal(sender.plane, null, "a malformed plane is not one");
});
