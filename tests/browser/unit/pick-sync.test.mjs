// web-client/net/pick-sync.js: the client's splats follow the session in the frame view.
import { test } from "node:test";
import assert from "node:assert/strict";

import { PickSync } from "../../../web-client/net/pick-sync.js";

// A session whose splats.get answers with its current revision after `delay` ms.
function fakeSession(delay = 5) {
  return {
    revision: 1,
    calls: 0,
    fail: false,
    async splatsSnapshot() {
      ++this.calls;
      const revision = this.revision;
      await new Promise((r) => setTimeout(r, delay));
      if (this.fail) throw new Error("refused");
      return { revision, payload: new Uint8Array([revision]) };
    },
  };
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

test("inactive (splat view) it fetches nothing; active it catches up with every change", async () => {
  const session = fakeSession();
  let held = 1;
  const applied = [];
  const sync = new PickSync(session, () => held, (b) => { held = b.revision; applied.push(b); }, 20);
  session.revision = 2;
  sync.changed();
  await sleep(30);
  assert.equal(session.calls, 0);
  sync.setActive(true);
  await sleep(30);
  assert.deepEqual(applied.map((b) => [b.full, b.revision]), [[true, 2]]);
  for (let r = 3; r <= 10; ++r) {
    session.revision = r;
    sync.changed();
    await sleep(2);
  }
  await sleep(120);
  assert.equal(held, 10, "it ends at the newest revision");
  assert.ok(session.calls <= 5, `changes in a burst are fetched together (${session.calls} requests)`);
  sync.setActive(false);
  session.revision = 11;
  sync.changed();
  await sleep(40);
  assert.equal(held, 10, "and stops with the frame view");
});

test("a failed request is not retried in a loop; the next change tries again", async () => {
  const session = fakeSession();
  let held = 1;
  const sync = new PickSync(session, () => held, (b) => (held = b.revision), 5);
  session.fail = true;
  session.revision = 2;
  sync.setActive(true);
  await sleep(60);
  assert.equal(session.calls, 1);
  session.fail = false;
  session.revision = 3;
  sync.changed();
  await sleep(30);
  assert.equal(held, 3);
});
