// The GPU copy of the splats, kept equal to a SplatStore brick by brick: a texture the vertex
// shader reads by vertex id ("vertex pulling"), so the splats draw as one plain drawArrays of
// six vertices per point, without instancing (SwiftShader, the software renderer of headless
// Chromium, spends ~20 us per instance; plain vertices cost a tenth of that, and on GPUs both
// are cheap).
// Conventions: two texels per point in an RGBA32UI texture TEXTURE_WIDTH texels wide; point i
// is texels 2i and 2i + 1 (t = 2i at (t % TEXTURE_WIDTH, floor(t / TEXTURE_WIDTH)); the width
// is even, so both lie in one row). The first: x, y, z as float32 bits (vu), and the normal
// packed as three 10-bit fields (round(511 n) + 512, x in bits 0-9, y in 10-19, z in 20-29)
// with bit 30 set for a point and bit 31 set when its normal varies; a texel without bit 30
// draws nothing. The second: the normal's gradient across the disc (math/splat-shading.js),
// dn/du in x and dn/dv in y, each as three 10-bit fields round(511 g / MAX_GRADIENT) + 512
// like the normal's; z the point's colour and mask, r | g << 8 | b << 16 | mask << 24 (sRGB
// bytes, protocol/js/splats.js); w is zero.
// Brick slots (in points) come from the store's allocator (render/slot-allocator.js). A
// changed brick is one or two texSubImage2D calls over its slot; the texture grows by whole
// rows, copying the old rows on the GPU (copyTexSubImage2D), never re-uploading from the CPU.
// Staging arrays are kept and reused; they grow with the largest upload, never per frame.
// Ownership: the caller's GL context; `texture` changes when it grows.

import { MAX_GRADIENT } from "../math/splat-shading.js";
import { CLAY_COLOR } from "../../protocol/js/splats.js";

export const TEXTURE_WIDTH = 2048;
const TEXEL_BYTES = 16;
const POINT_TEXELS = 2;
const POINT_BYTES = POINT_TEXELS * TEXEL_BYTES;
const MIN_ROWS = 8;
const GROWTH = 1.5;
const VALID = 1 << 30;
const VARIES = 2 ** 31;
// Points that came without colours (none of the store's: the decoder gives every point one).
const CLAY_PACKED = CLAY_COLOR[0] | (CLAY_COLOR[1] << 8) | (CLAY_COLOR[2] << 16);

export class SplatBuffer {
  constructor(gl) {
    this.gl = gl;
    this.rows = 0;
    this.texture = null;
    this.staging = new ArrayBuffer(0);
    this.brickStaging = new ArrayBuffer(512 * POINT_BYTES);
    this.uploadedBytes = 0; // total bytes sent to the GPU, for the statistics panel
    this.maxRows = gl.getParameter(gl.MAX_TEXTURE_SIZE);
  }

  get capacity() {
    return (this.rows * TEXTURE_WIDTH) / POINT_TEXELS;
  }

  // Applies the store's changes since the last sync.
  sync(store) {
    const changes = store.takeChanges();
    const gl = this.gl;
    const count = store.slotCount;
    if (changes.repack) {
      const rows = Math.ceil((count * POINT_TEXELS) / TEXTURE_WIDTH);
      const bytes = rows * TEXTURE_WIDTH * TEXEL_BYTES;
      if (this.staging.byteLength < bytes) this.staging = new ArrayBuffer(Math.ceil(bytes * GROWTH));
      new Uint8Array(this.staging, 0, bytes).fill(0);
      for (const entry of store.bricks.values()) fill(this.staging, entry.slot.offset, entry);
      if (rows > this.rows || !this.texture) this.#allocate(Math.max(MIN_ROWS, Math.ceil(rows * GROWTH)), false, rows);
      if (rows) {
        gl.bindTexture(gl.TEXTURE_2D, this.texture);
        gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, TEXTURE_WIDTH, rows, gl.RGBA_INTEGER, gl.UNSIGNED_INT, new Uint32Array(this.staging, 0, bytes / 4));
      }
      this.uploadedBytes += bytes;
      return;
    }
    if (count > this.capacity) this.#allocate(Math.ceil((count * POINT_TEXELS * GROWTH) / TEXTURE_WIDTH), true, this.rows);
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    for (const slot of changes.clears) {
      new Uint8Array(this.brickStaging, 0, slot.capacity * POINT_BYTES).fill(0);
      this.#upload(slot);
    }
    for (const entry of changes.writes) {
      new Uint8Array(this.brickStaging, 0, entry.slot.capacity * POINT_BYTES).fill(0);
      fill(this.brickStaging, 0, entry);
      this.#upload(entry.slot);
    }
  }

  // The slot's texels from brickStaging, split where the slot wraps to the next row.
  #upload(slot) {
    const gl = this.gl;
    const first = slot.offset * POINT_TEXELS, count = slot.capacity * POINT_TEXELS;
    let done = 0;
    while (done < count) {
      const i = first + done;
      const x = i % TEXTURE_WIDTH;
      const n = Math.min(count - done, TEXTURE_WIDTH - x);
      const texels = new Uint32Array(this.brickStaging, done * TEXEL_BYTES, n * 4);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x, Math.floor(i / TEXTURE_WIDTH), n, 1, gl.RGBA_INTEGER, gl.UNSIGNED_INT, texels);
      done += n;
    }
    this.uploadedBytes += slot.capacity * POINT_BYTES;
  }

  // A new texture of `rows` rows; `keep` copies the old rows over on the GPU. Rows from
  // `definedRows` on are zeroed (the rows before it are copied, or uploaded by the caller).
  #allocate(rows, keep, definedRows) {
    rows = Math.min(rows, this.maxRows);
    const gl = this.gl;
    const next = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, next);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32UI, TEXTURE_WIDTH, rows);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    if (this.texture) {
      if (keep && this.rows) {
        const fb = gl.createFramebuffer();
        gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb);
        gl.framebufferTexture2D(gl.READ_FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.texture, 0);
        gl.copyTexSubImage2D(gl.TEXTURE_2D, 0, 0, 0, 0, 0, TEXTURE_WIDTH, this.rows);
        gl.bindFramebuffer(gl.READ_FRAMEBUFFER, null);
        gl.deleteFramebuffer(fb);
      }
      gl.deleteTexture(this.texture);
    }
    if (rows > definedRows) {
      // Texels of texStorage2D are undefined until written; unused ones must read as "no point".
      const zeros = new Uint32Array(TEXTURE_WIDTH * (rows - definedRows) * 4);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, definedRows, TEXTURE_WIDTH, rows - definedRows, gl.RGBA_INTEGER, gl.UNSIGNED_INT, zeros);
    }
    this.texture = next;
    this.rows = rows;
  }

  // Forgets the GPU objects (the context was lost); the next sync must be a repack.
  lost() {
    this.texture = null;
    this.rows = 0;
  }
}

// Writes the points of `entry` as texels starting at point `first` of `target`.
function fill(target, first, entry) {
  const words = 4 * POINT_TEXELS;
  const f32 = new Float32Array(target, first * POINT_BYTES, entry.count * words);
  const u32 = new Uint32Array(target, first * POINT_BYTES, entry.count * words);
  const p = entry.positions, n = entry.normals, g = entry.gradients, c = entry.colors;
  for (let k = 0, j = 0; k < entry.count; ++k, j += 3) {
    const o = words * k;
    const i = 4 * k;
    u32[o + 6] = c ? (c[i] | (c[i + 1] << 8) | (c[i + 2] << 16) | (c[i + 3] << 24)) >>> 0 : CLAY_PACKED;
    f32[o] = p[j];
    f32[o + 1] = p[j + 1];
    f32[o + 2] = p[j + 2];
    let varies = 0;
    const q = 6 * k;
    if (g && (g[q] || g[q + 1] || g[q + 2] || g[q + 3] || g[q + 4] || g[q + 5])) {
      u32[o + 4] = packNormal(g[q] / MAX_GRADIENT, g[q + 1] / MAX_GRADIENT, g[q + 2] / MAX_GRADIENT);
      u32[o + 5] = packNormal(g[q + 3] / MAX_GRADIENT, g[q + 4] / MAX_GRADIENT, g[q + 5] / MAX_GRADIENT);
      varies = VARIES;
    }
    u32[o + 3] = (VALID | packNormal(n[j], n[j + 1], n[j + 2])) + varies;
  }
}

function packNormal(x, y, z) {
  return snorm10(x) | (snorm10(y) << 10) | (snorm10(z) << 20);
}

function snorm10(v) {
  return Math.round(Math.max(-1, Math.min(1, v)) * 511) + 512;
}
