// web-client/net/presence-sender.js: the throttle (at most one presence per interval, the
// newest state at the time it goes out), repeats skipped until a refresh is due, and what a
// presence holds (no brush for a view client or off the model; a camera the protocol refuses
// left out).
import { test } from "node:test";
import assert from "node:assert/strict";

import { PRESENCE_INTERVAL_MS, presenceParams } from "../../../protocol/js/presence.js";
import { PRESENCE_REFRESH_MS, PresenceSender, STALE_MS, Throttle, composePresence } from "../../../web-client/net/presence-sender.js";

// A clock and timers that move only when told.
function fakeTime() {
  let now = 0;
  let timers = [];
  let nextId = 1;
  const clock = {
    now: () => now,
    setTimer: (f, ms) => {
      const id = nextId++;
      timers.push({ id, at: now + ms, f, every: 0 });
      return id;
    },
    setRepeat: (f, ms) => {
      const id = nextId++;
      timers.push({ id, at: now + ms, f, every: ms });
      return id;
    },
    clearTimer: (id) => (timers = timers.filter((t) => t.id !== id)),
    advance(ms) {
      const end = now + ms;
      for (;;) {
        const due = timers.filter((t) => t.at <= end).sort((a, b) => a.at - b.at)[0];
        if (!due) break;
        now = due.at;
        if (due.every) due.at += due.every;
        else timers = timers.filter((t) => t !== due);
        due.f();
      }
      now = end;
    },
    get pending() {
      return timers.filter((t) => !t.every).length;
    },
  };
  clock.clearRepeat = clock.clearTimer;
  return clock;
}

test("the throttle fires at once, then at most once per interval, however often it is poked", () => {
  const t = fakeTime();
  const fired = [];
  const throttle = new Throttle(50, () => fired.push(t.now()), t);
  throttle.poke();
  assert.deepEqual(fired, [0], "the first poke fires at once");
  for (let ms = 0; ms < 200; ms += 5) {
    t.advance(5);
    throttle.poke();
  }
  // pokes every 5 ms for 200 ms: fires at 0, 50, 100, 150, 200 and never closer than 50 ms
  assert.deepEqual(fired, [0, 50, 100, 150, 200]);
  t.advance(500);
  assert.deepEqual(fired.slice(5), [250], "the last poke (at 200) fires once its interval is up, then nothing more");
  throttle.poke();
  assert.deepEqual(fired.at(-1), 700, "a poke after a quiet spell fires at once");
  throttle.poke();
  throttle.cancel();
  t.advance(100);
  assert.equal(fired.length, 7, "a cancelled timer does not fire");
});

test("the sender sends the newest state when the interval is up, skips repeats, refreshes a resting one", () => {
  const t = fakeTime();
  let state = { x: 1 };
  const sent = [];
  const sender = new PresenceSender({ compose: () => ({ ...state }), send: (p) => (sent.push([t.now(), p.x]), true), intervalMs: PRESENCE_INTERVAL_MS, ...t });
  sender.poke();
  state = { x: 2 };
  sender.poke();
  state = { x: 3 };
  sender.poke();
  t.advance(PRESENCE_INTERVAL_MS);
  assert.deepEqual(sent, [[0, 1], [PRESENCE_INTERVAL_MS, 3]], "x = 2 was replaced before it went out (latest wins)");
  sender.poke();
  t.advance(PRESENCE_INTERVAL_MS);
  assert.equal(sent.length, 2, "an unchanged presence is not sent again");
  t.advance(PRESENCE_REFRESH_MS);
  assert.equal(sent.length, 3, "but is refreshed every PRESENCE_REFRESH_MS");
  assert.deepEqual(sent[2][1], 3);
  sender.resend();
  assert.equal(sent.length, 4, "resend() sends it again at once (a new client joined)");
  assert.ok(STALE_MS >= 2 * PRESENCE_REFRESH_MS, "a receiver waits for more than one refresh before calling a ring stale");
  // Over a second of pointer moves every 8 ms (120 Hz), at most 1000 / interval + 1 sends.
  const before = sent.length;
  for (let ms = 0; ms < 1000; ms += 8) {
    state = { x: ms };
    sender.poke();
    t.advance(8);
  }
  assert.ok(sent.length - before <= 1000 / PRESENCE_INTERVAL_MS + 1, `${sent.length - before} sends in a second`);
  assert.ok(sent.length - before >= 1000 / PRESENCE_INTERVAL_MS - 1);
  sender.stop();
  state = { x: -1 };
  t.advance(3 * PRESENCE_REFRESH_MS);
  assert.notEqual(sent.at(-1)[1], -1, "a stopped sender sends nothing");
  // A send that could not go out (offline, a full socket) is tried again at the next poke.
  const t2 = fakeTime();
  let open = false;
  const out = [];
  const s2 = new PresenceSender({ compose: () => ({ x: 1 }), send: (p) => open && out.push(p), intervalMs: 50, ...t2 });
  s2.poke();
  open = true;
  t2.advance(60);
  s2.poke();
  assert.equal(out.length, 1);
  s2.stop();
});

test("a presence: the brush only on the model of an editable session, the camera unless the protocol refuses it", () => {
  const camera = { eye: [64, 64, 300], target: [64, 64, 64], up: [0, 1, 0], fov: 40 };
  const brush = { tool: "remove_blob", radius: 8, point: [60, 70, 100], normal: [0, 0, 2], active: true };
  assert.deepEqual(composePresence({ brush, camera, readOnly: false }, presenceParams), { brush, camera });
  assert.deepEqual(composePresence({ brush, camera, readOnly: true }, presenceParams), { camera }, "a view client sends no brush");
  assert.deepEqual(composePresence({ brush: null, camera, readOnly: false }, presenceParams), { camera }, "off the model, no brush");
  assert.equal(composePresence({ brush: { ...brush, radius: 2000 }, camera, readOnly: false }, presenceParams).brush.radius, 1024, "radius within the protocol's range");
  const far = { ...camera, eye: [64, 64, 2e5] };
  assert.deepEqual(composePresence({ brush, camera: far, readOnly: false }, presenceParams), { brush }, "an eye beyond 1e5 vu is left out");
  assert.throws(() => composePresence({ brush: { ...brush, tool: "no_such_tool" }, camera, readOnly: false }, presenceParams), RangeError, "a programming error still throws");
});
