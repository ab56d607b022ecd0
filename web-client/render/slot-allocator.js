// Slots of the splat texture (render/splat-buffer.js): one contiguous run of points per brick.
// Conventions: offsets and capacities count points (texels), not bytes. Capacities are
// multiples of SLOT_STEP up to MAX_SLOT (512, the most points a brick can have): a full buffer
// packs each brick into the smallest slot that holds it; a brick rewritten by a delta gets
// `headroom` more, so that the small changes of the next edits fit in place. Freed slots go to
// a free list per capacity and are reused by bricks of that class. The drawn range is
// [0, highWater); points in it that belong to no brick, or lie past their brick's count, are
// marked invalid and draw nothing. Pure bookkeeping: no GL here.

export const SLOT_STEP = 16;
export const MAX_SLOT = 512;
// A slot this much larger than its brick needs is given up for a smaller one.
const MAX_SLACK = 4 * SLOT_STEP;

// The smallest capacity class that holds `count` points (1..512).
export function slotClass(count) {
  if (!(count >= 1 && count <= MAX_SLOT)) throw new RangeError(`a brick holds 1 to ${MAX_SLOT} points, got ${count}`);
  return Math.ceil(count / SLOT_STEP) * SLOT_STEP;
}

export class SlotAllocator {
  constructor() {
    this.reset();
  }

  // Forgets every slot.
  reset() {
    this.highWater = 0; // points from 0 to here may be drawn
    this.liveCapacity = 0; // sum of the capacities of allocated slots
    this.free = new Map(); // capacity -> offsets of freed slots
  }

  // {offset, capacity} of a new slot for `count` points and up to `headroom` more.
  allocate(count, headroom = 0) {
    const capacity = slotClass(Math.min(MAX_SLOT, count + headroom));
    this.liveCapacity += capacity;
    const reusable = this.free.get(capacity);
    if (reusable && reusable.length) return { offset: reusable.pop(), capacity };
    const offset = this.highWater;
    this.highWater += capacity;
    return { offset, capacity };
  }

  release(slot) {
    this.liveCapacity -= slot.capacity;
    let list = this.free.get(slot.capacity);
    if (!list) this.free.set(slot.capacity, (list = []));
    list.push(slot.offset);
  }

  // True when `count` points may be written into `slot` in place: they fit, and the slot is not
  // much larger than they need (a brick that shrank a lot moves to a smaller slot).
  fits(slot, count) {
    return count <= slot.capacity && slot.capacity - slotClass(count) <= MAX_SLACK;
  }

  // True when freed slots waste a good part of the drawn range (and enough to matter): then
  // repacking every brick is cheaper than drawing the holes frame after frame.
  fragmented() {
    return this.highWater > 8192 && this.liveCapacity < 0.7 * this.highWater;
  }
}
