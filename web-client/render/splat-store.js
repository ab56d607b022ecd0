// The client's copy of the session's splats, brick by brick, and the record of what the GPU
// buffer must change to match it.
// Conventions: positions in vu, normals unit, colours r, g, b, mask bytes per point (sRGB;
// render/../protocol/js/splats.js decodes them);
// a brick's key is x + 65536 (y + 65536 z) of its brick coordinates. A full buffer replaces
// everything; a delta replaces the listed bricks and removes those with 0 points
// (PROTOCOL.md, "Binary frames"). The store keeps the decoded arrays it is given (views into
// the decoded message), so a brick costs no copy on the CPU side. Each point is drawn as a disc
// of DISC_RADIUS vu; each brick also keeps the rate of change of its discs' normals
// (`gradients`, math/splat-shading.js), fitted when the brick arrives and fitted again for its
// neighbours (whose fits use its points), which are uploaded again only if theirs changed.
// Ownership: SplatBuffer (render/splat-buffer.js) consumes the changes with takeChanges().

import { normalGradients } from "../math/splat-shading.js";
import { SlotAllocator } from "./slot-allocator.js";

// A little over half the voxel spacing, so that the discs of neighbouring voxels overlap
// without holes at any zoom (render/splat-renderer.js draws them, math/splat-pick.js picks them).
export const DISC_RADIUS = 0.8;

const BRICK = 8;
// Extra points of room for a brick that a delta moves to a new slot: edits come in runs.
const DELTA_HEADROOM = 16;

export function brickKey(b) {
  return b[0] + 65536 * (b[1] + 65536 * b[2]);
}

export class SplatStore {
  constructor() {
    this.varyNormals = true; // false: one flat normal per disc, for comparisons
    this.allocator = new SlotAllocator();
    this.bricks = new Map(); // key -> {brick, count, positions, normals, colors, gradients, slot}
    this.pointCount = 0;
    this.revision = 0; // revision of the newest buffer applied (a Number)
    this.version = 0; // grows with every change, for views that cache derived data
    this.repack = true; // the next takeChanges() is a full upload
    this.writes = new Set(); // entries whose points must be uploaded
    this.clears = []; // slots released since the last takeChanges()
  }

  // Decoded kind-1 payload (protocol/js/splats.js): replaces everything.
  applyFull(decoded, revision) {
    this.bricks.clear();
    this.pointCount = 0;
    for (const b of decoded.bricks) {
      if (b.count === 0) continue;
      this.bricks.set(brickKey(b.brick), { brick: b.brick, count: b.count, positions: b.positions, normals: b.normals, colors: b.colors, gradients: null, slot: null });
      this.pointCount += b.count;
    }
    for (const entry of this.bricks.values()) entry.gradients = this.#gradientsOf(entry);
    this.#packAll();
    this.revision = revision;
    ++this.version;
  }

  // Decoded kind-2 payload: each listed brick replaces its old points; 0 points removes it.
  applyDelta(decoded, revision) {
    for (const b of decoded.bricks) {
      const key = brickKey(b.brick);
      const old = this.bricks.get(key);
      if (old) {
        this.pointCount -= old.count;
        if (b.count === 0 || !this.allocator.fits(old.slot, b.count)) {
          this.#release(old);
        }
      }
      if (b.count === 0) {
        this.bricks.delete(key);
        continue;
      }
      const entry = { brick: b.brick, count: b.count, positions: b.positions, normals: b.normals, colors: b.colors, gradients: null, slot: null };
      entry.slot = old && old.slot && this.allocator.fits(old.slot, b.count) ? old.slot : this.allocator.allocate(b.count, DELTA_HEADROOM);
      if (old) this.writes.delete(old);
      this.bricks.set(key, entry);
      this.writes.add(entry);
      this.pointCount += b.count;
    }
    this.#refit(decoded.bricks.map((b) => b.brick));
    if (this.allocator.fragmented()) this.#packAll();
    this.revision = Math.max(this.revision, revision);
    ++this.version;
  }

  // The GPU copy is gone (a lost context): the next takeChanges() uploads everything again.
  requestRepack() {
    this.repack = true;
  }

  clear() {
    this.bricks.clear();
    this.pointCount = 0;
    this.#packAll();
    ++this.version;
  }

  // What changed since the last call: {repack: true} means "upload every brick at its slot and
  // draw nothing else"; otherwise `clears` are slots to mark invalid (before the writes, which
  // may reuse them) and `writes` are bricks to upload.
  takeChanges() {
    const changes = { repack: this.repack, clears: this.clears, writes: [...this.writes] };
    this.repack = false;
    this.clears = [];
    this.writes.clear();
    return changes;
  }

  // Point slots the GPU must draw (live or not): the allocator's high-water mark.
  get slotCount() {
    return this.allocator.highWater;
  }

  // The box of the voxels of every brick with points, {lo, hi} in vu, or null when empty.
  bounds() {
    if (this.bricks.size === 0) return null;
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (const { brick } of this.bricks.values())
      for (let k = 0; k < 3; ++k) {
        lo[k] = Math.min(lo[k], BRICK * brick[k]);
        hi[k] = Math.max(hi[k], BRICK * brick[k] + BRICK - 1);
      }
    return { lo, hi };
  }

  // The box of the points themselves, {lo, hi} in vu, or null when there are none.
  pointBounds() {
    if (this.pointCount === 0) return null;
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (const { count, positions } of this.bricks.values())
      for (let i = 0; i < 3 * count; i += 3)
        for (let k = 0; k < 3; ++k) {
          lo[k] = Math.min(lo[k], positions[i + k]);
          hi[k] = Math.max(hi[k], positions[i + k]);
        }
    return { lo, hi };
  }

  // The normal gradients of `entry` from the points of its brick and the 26 around it.
  #gradientsOf(entry) {
    return this.varyNormals ? normalGradients(entry, this.#around(entry.brick)) : null;
  }

  #around(brick) {
    const list = [];
    for (let z = -1; z <= 1; ++z)
      for (let y = -1; y <= 1; ++y)
        for (let x = -1; x <= 1; ++x) {
          const e = this.bricks.get(brickKey([brick[0] + x, brick[1] + y, brick[2] + z]));
          if (e) list.push(e);
        }
    return list;
  }

  // New gradients for the changed bricks (`bricks`, coordinates) and every brick next to one; a
  // neighbour whose gradients changed is uploaded again.
  #refit(bricks) {
    const todo = new Map();
    for (const b of bricks)
      for (let z = -1; z <= 1; ++z)
        for (let y = -1; y <= 1; ++y)
          for (let x = -1; x <= 1; ++x) {
            const key = brickKey([b[0] + x, b[1] + y, b[2] + z]);
            const e = this.bricks.get(key);
            if (e) todo.set(key, e);
          }
    for (const e of todo.values()) {
      const gradients = this.#gradientsOf(e);
      const changed = !sameArray(gradients, e.gradients);
      e.gradients = gradients;
      if (changed && e.slot) this.writes.add(e);
    }
  }

  // Varying normals on or off, everywhere (every brick is uploaded again).
  setVaryNormals(on) {
    this.varyNormals = on;
    for (const e of this.bricks.values()) e.gradients = this.#gradientsOf(e);
    this.repack = true;
    ++this.version;
  }

  #release(entry) {
    if (!entry.slot) return;
    this.allocator.release(entry.slot);
    this.clears.push(entry.slot);
    this.writes.delete(entry);
    entry.slot = null;
  }

  // Every brick into a fresh, gapless run of slots (in map order).
  #packAll() {
    this.allocator.reset();
    for (const entry of this.bricks.values()) entry.slot = this.allocator.allocate(entry.count);
    this.repack = true;
    this.clears = [];
    this.writes.clear();
  }
}

function sameArray(a, b) {
  if (a === b) return true;
  if (!a || !b || a.length !== b.length) return false;
  for (let i = 0; i < a.length; ++i) if (a[i] !== b[i]) return false;
  return true;
}
