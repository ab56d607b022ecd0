// The GPU copy of the splats, kept equal to a SplatStore brick by brick: a texture the vertex
// shader reads by vertex id ("vertex pulling"), so the splats draw as one plain drawArrays of
// six vertices per point, without instancing (SwiftShader, the software renderer of headless
// Chromium, spends ~20 us per instance; plain vertices cost a tenth of that, and on GPUs both
// are cheap).
// Conventions: one texel per point in an RGBA32UI texture TEXTURE_WIDTH texels wide; point i
// is texel (i % TEXTURE_WIDTH, floor(i / TEXTURE_WIDTH)). Its channels: x, y, z as float32 bits
// (vu), and the normal packed as three 10-bit fields (round(511 n) + 512, x in bits 0-9, y in
// 10-19, z in 20-29) with bit 30 set for a point; a texel without bit 30 draws nothing. Brick
// slots come from the store's allocator (render/slot-allocator.js). A changed brick is one or
// two texSubImage2D calls over its slot; the texture grows by whole rows, copying the old rows
// on the GPU (copyTexSubImage2D), never re-uploading from the CPU. Staging arrays are kept and
// reused; they grow with the largest upload, never per frame.
// Ownership: the caller's GL context; `texture` changes when it grows.

export const TEXTURE_WIDTH = 2048;
const TEXEL_BYTES = 16;
const MIN_ROWS = 8;
const GROWTH = 1.5;
const VALID = 1 << 30;

export class SplatBuffer {
  constructor(gl) {
    this.gl = gl;
    this.rows = 0;
    this.texture = null;
    this.staging = new ArrayBuffer(0);
    this.brickStaging = new ArrayBuffer(512 * TEXEL_BYTES);
    this.uploadedBytes = 0; // total bytes sent to the GPU, for the statistics panel
    this.maxRows = gl.getParameter(gl.MAX_TEXTURE_SIZE);
  }

  get capacity() {
    return this.rows * TEXTURE_WIDTH;
  }

  // Applies the store's changes since the last sync.
  sync(store) {
    const changes = store.takeChanges();
    const gl = this.gl;
    const count = store.slotCount;
    if (changes.repack) {
      const rows = Math.ceil(count / TEXTURE_WIDTH);
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
    if (count > this.capacity) this.#allocate(Math.ceil((count * GROWTH) / TEXTURE_WIDTH), true, this.rows);
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    for (const slot of changes.clears) {
      new Uint8Array(this.brickStaging, 0, slot.capacity * TEXEL_BYTES).fill(0);
      this.#upload(slot);
    }
    for (const entry of changes.writes) {
      new Uint8Array(this.brickStaging, 0, entry.slot.capacity * TEXEL_BYTES).fill(0);
      fill(this.brickStaging, 0, entry);
      this.#upload(entry.slot);
    }
  }

  // The slot's texels from brickStaging, split where the slot wraps to the next row.
  #upload(slot) {
    const gl = this.gl;
    let done = 0;
    while (done < slot.capacity) {
      const i = slot.offset + done;
      const x = i % TEXTURE_WIDTH;
      const n = Math.min(slot.capacity - done, TEXTURE_WIDTH - x);
      const texels = new Uint32Array(this.brickStaging, done * TEXEL_BYTES, n * 4);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x, Math.floor(i / TEXTURE_WIDTH), n, 1, gl.RGBA_INTEGER, gl.UNSIGNED_INT, texels);
      done += n;
    }
    this.uploadedBytes += slot.capacity * TEXEL_BYTES;
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

// Writes the points of `entry` as texels starting at texel `first` of `target`.
function fill(target, first, entry) {
  const f32 = new Float32Array(target, first * TEXEL_BYTES, entry.count * 4);
  const u32 = new Uint32Array(target, first * TEXEL_BYTES, entry.count * 4);
  const p = entry.positions, n = entry.normals;
  for (let k = 0, j = 0; k < entry.count; ++k, j += 3) {
    f32[4 * k] = p[j];
    f32[4 * k + 1] = p[j + 1];
    f32[4 * k + 2] = p[j + 2];
    u32[4 * k + 3] = (VALID | snorm10(n[j]) | (snorm10(n[j + 1]) << 10) | (snorm10(n[j + 2]) << 20)) >>> 0;
  }
}

function snorm10(v) {
  return Math.round(Math.max(-1, Math.min(1, v)) * 511) + 512;
}
