// web-client/render/splat-store.js and slot-allocator.js: the client's bricks of splats and the
// GPU slots they occupy, fed with buffers decoded by protocol/js/splats.js.
import { test } from "node:test";
import assert from "node:assert/strict";

import { decodeSplats } from "../../../protocol/js/splats.js";
import { SplatStore } from "../../../web-client/render/splat-store.js";
import { MAX_SLOT, SLOT_STEP, SlotAllocator, slotClass } from "../../../web-client/render/slot-allocator.js";

// A splat buffer (protocol/cpp/splats.hpp) of bricks [{brick, count}] with points at the
// brick's origin and normal +z.
function encode(bricks) {
  const points = bricks.reduce((n, b) => n + b.count, 0);
  const bytes = new Uint8Array(16 + 8 * bricks.length + 8 * points);
  const v = new DataView(bytes.buffer);
  bytes.set([0x4d, 0x5a, 0x53, 0x50]);
  v.setUint16(4, 1, true);
  v.setUint32(8, bricks.length, true);
  v.setUint32(12, points, true);
  let at = 16;
  for (const b of bricks) {
    b.brick.forEach((c, i) => v.setUint16(at + 2 * i, c, true));
    v.setUint16(at + 6, b.count, true);
    at += 8;
    for (let k = 0; k < b.count; ++k, at += 8) {
      const code = Math.round((2 * 16384) / 12); // 2 vu into the brick's range: its origin
      v.setUint32(at, (code | (code << 14) | (code << 28)) >>> 0, true);
      v.setUint32(at + 4, ((code >>> 4) | (1023 << 10) | (1023 << 21)) >>> 0, true);
    }
  }
  const decoded = decodeSplats(bytes);
  assert.ok(decoded.ok, decoded.message);
  return decoded;
}

// Live slots lie within the drawn range, hold their brick and never overlap.
function checkSlots(store) {
  const slots = [...store.bricks.values()].map((e) => {
    assert.ok(e.slot, "every brick has a slot");
    assert.ok(e.count <= e.slot.capacity);
    assert.ok(e.slot.offset >= 0 && e.slot.offset + e.slot.capacity <= store.slotCount);
    return e.slot;
  });
  slots.sort((a, b) => a.offset - b.offset);
  for (let i = 1; i < slots.length; ++i) assert.ok(slots[i - 1].offset + slots[i - 1].capacity <= slots[i].offset, "slots overlap");
  assert.equal(store.pointCount, [...store.bricks.values()].reduce((n, e) => n + e.count, 0));
}

test("slot classes are multiples of SLOT_STEP up to 512", () => {
  assert.equal(slotClass(1), SLOT_STEP);
  assert.equal(slotClass(16), 16);
  assert.equal(slotClass(17), 32);
  assert.equal(slotClass(512), MAX_SLOT);
  assert.throws(() => slotClass(0), RangeError);
  assert.throws(() => slotClass(513), RangeError);
  const a = new SlotAllocator();
  const s = a.allocate(20, 16);
  assert.deepEqual(s, { offset: 0, capacity: 48 });
  a.release(s);
  assert.deepEqual(a.allocate(40), { offset: 0, capacity: 48 }, "a freed slot of the class is reused");
  assert.ok(a.fits({ offset: 0, capacity: 48 }, 48) && !a.fits({ offset: 0, capacity: 48 }, 49));
  assert.ok(!a.fits({ offset: 0, capacity: 512 }, 10), "a slot far too big for its brick is given up");
});

test("a full buffer replaces everything and is packed without gaps", () => {
  const store = new SplatStore();
  store.applyFull(encode([{ brick: [0, 0, 0], count: 5 }, { brick: [1, 0, 0], count: 16 }, { brick: [2, 3, 4], count: 300 }]), 7);
  assert.equal(store.pointCount, 321);
  assert.equal(store.bricks.size, 3);
  assert.equal(store.revision, 7);
  assert.equal(store.slotCount, 16 + 16 + 304);
  checkSlots(store);
  assert.deepEqual(store.bounds(), { lo: [0, 0, 0], hi: [23, 31, 39] });
  assert.equal(store.takeChanges().repack, true);
  assert.equal(store.takeChanges().repack, false, "changes are taken once");
  store.applyFull(encode([{ brick: [9, 9, 9], count: 1 }]), 8);
  assert.equal(store.pointCount, 1);
  assert.equal(store.slotCount, 16);
  assert.deepEqual(store.bounds(), { lo: [72, 72, 72], hi: [79, 79, 79] });
});

test("a delta rewrites bricks in place when they fit, moves them when not, removes empty ones", () => {
  const store = new SplatStore();
  store.applyFull(encode([{ brick: [0, 0, 0], count: 10 }, { brick: [1, 0, 0], count: 30 }, { brick: [2, 0, 0], count: 8 }]), 1);
  store.takeChanges();
  const before = new Map([...store.bricks].map(([k, e]) => [k, e.slot]));
  store.applyDelta(encode([{ brick: [0, 0, 0], count: 12 }, { brick: [1, 0, 0], count: 40 }, { brick: [2, 0, 0], count: 0 }, { brick: [3, 0, 0], count: 3 }]), 2);
  checkSlots(store);
  assert.equal(store.pointCount, 12 + 40 + 3);
  assert.equal(store.bricks.size, 3, "the brick with 0 points is gone");
  const slot = (b) => store.bricks.get(b[0] + 65536 * (b[1] + 65536 * b[2])).slot;
  assert.equal(slot([0, 0, 0]), before.get(0), "12 points still fit the 16-point slot: in place");
  assert.notEqual(slot([1, 0, 0]).offset, before.get(1).offset, "40 points do not fit 32: moved");
  const changes = store.takeChanges();
  assert.equal(changes.repack, false);
  assert.equal(changes.writes.length, 3);
  assert.deepEqual(changes.clears.map((s) => s.offset).sort((a, b) => a - b), [before.get(1).offset, before.get(2).offset]);
  assert.equal(store.revision, 2);
});

test("many edits reuse freed slots, and a fragmented layout is repacked", () => {
  const store = new SplatStore();
  const bricks = [];
  for (let i = 0; i < 400; ++i) bricks.push({ brick: [i % 20, Math.floor(i / 20), 0], count: 40 });
  store.applyFull(encode(bricks), 1);
  store.takeChanges();
  let repacked = false;
  for (let round = 0; round < 30; ++round) {
    const delta = [];
    for (let i = round % 3; i < 400; i += 3) delta.push({ brick: bricks[i].brick, count: 1 + ((i * 7 + round * 13) % 512) });
    store.applyDelta(encode(delta), 2 + round);
    checkSlots(store);
    repacked ||= store.takeChanges().repack;
  }
  assert.ok(repacked, "random growth and shrinking fragment the slots until a repack");
  assert.ok(store.allocator.liveCapacity >= 0.7 * store.slotCount || store.slotCount <= 8192, "the drawn range stays mostly live");
});
