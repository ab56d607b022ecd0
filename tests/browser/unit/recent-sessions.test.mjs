// web-client/ui/recent-sessions.js: the sessions this browser opened, kept in its storage.
import { test } from "node:test";
import assert from "node:assert/strict";

import { MAX_RECENT, RecentSessions } from "../../../web-client/ui/recent-sessions.js";

// An in-memory Web Storage with the same methods as window.localStorage.
class MemoryStorage {
  items = new Map();
  getItem(k) {
    return this.items.has(k) ? this.items.get(k) : null;
  }
  setItem(k, v) {
    this.items.set(k, String(v));
  }
}

test("newest first, one entry per session, at most MAX_RECENT", () => {
  const recent = new RecentSessions(new MemoryStorage());
  for (let i = 0; i < MAX_RECENT + 3; ++i) recent.remember({ session: `s${i}`, token: `t${i}`, readOnly: false, size: [64, 64, 64] }, 1000 + i);
  recent.remember({ session: "s5", token: "t5", readOnly: false, size: [64, 64, 64] }, 5000);
  const list = recent.list();
  assert.equal(list.length, MAX_RECENT);
  assert.equal(list[0].session, "s5");
  assert.equal(list[0].openedAt, 5000);
  assert.equal(list.filter((e) => e.session === "s5").length, 1);
  assert.equal(list[1].session, `s${MAX_RECENT + 2}`);
});

test("an edit token is not replaced by a view token of the same session", () => {
  const recent = new RecentSessions(new MemoryStorage());
  recent.remember({ session: "a", token: "edit", readOnly: false, size: [128, 128, 128] }, 1);
  recent.remember({ session: "a", token: "view", readOnly: true, size: [128, 128, 128] }, 2);
  assert.deepEqual(recent.list(), [{ session: "a", token: "edit", readOnly: false, size: [128, 128, 128], front: null, openedAt: 2 }]);
  recent.forget("a");
  assert.deepEqual(recent.list(), []);
});

test("the model's front is kept, and not lost by a later visit that does not know it", () => {
  const recent = new RecentSessions(new MemoryStorage());
  recent.remember({ session: "p", token: "edit", readOnly: false, size: [128, 128, 128], front: "+x" }, 1);
  recent.remember({ session: "p", token: "edit", readOnly: false, size: [128, 128, 128] }, 2);
  assert.equal(recent.find("p").front, "+x");
  assert.equal(recent.find("nothing"), null);
});

test("garbage in the storage, or no storage at all, gives an empty list", () => {
  const storage = new MemoryStorage();
  storage.setItem("marzipan.recent-sessions", "{not json");
  assert.deepEqual(new RecentSessions(storage).list(), []);
  storage.setItem("marzipan.recent-sessions", JSON.stringify([{ session: 3 }, "x"]));
  assert.deepEqual(new RecentSessions(storage).list(), []);
  const none = new RecentSessions(null);
  none.remember({ session: "a", token: "t", readOnly: false, size: [1, 1, 1] });
  assert.deepEqual(none.list(), []);
});
