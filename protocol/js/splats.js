// Splat buffers: the payload of binary frames of kind 1 (splats full) and 2 (splats delta).
// protocol/cpp/splats.hpp specifies the format byte by byte; this decoder mirrors its C++
// decodeSplats check for check, and gives the same float values (each step rounded to float32
// as the C++ code does).
//
// Conventions: integers little-endian; positions in vu of the session grid (voxel (i, j, k) at
// (i, j, k)); normals unit length, outward; colours sRGB bytes, mask 0 (free) .. 255 (frozen).
// Layout:
//   header, 16 bytes: "MZSP", u16 version (1 or 2), u16 reserved = 0, u32 B bricks, u32 total points
//   B blocks: u16 brick x, y, z (voxel / 8), u16 N, then the points. Version 1: N is the count
//   (0..512; 0 = the brick has no points), each point a u64. Version 2: N's bits 0..9 are the
//   count n (0..512), bit 15 is set when the brick is painted (then n >= 1), bits 10..14 are 0;
//   a painted brick's points are 12 bytes, the u64 then u8 r, g, b, mask; an unpainted brick's
//   are the u64 alone and take the session's base_color with mask 0. Nothing after the last block.
//   The u64: bits 0..13 X, 14..27 Y, 28..41 Z (position codes), 42..52 U, 53..63 V
//   (octahedral normal).
//   Position per axis: 8 * brick + C * 3 / 4096 - 2, i.e. [-2, 10) vu around the brick origin,
//   error <= 3.7e-4 vu. Normal: u = (2U - 2047) / 2047, v = (2V - 2047) / 2047,
//   z = 1 - |u| - |v|; where z < 0, (u, v) <- ((1 - |v|) sign(u), (1 - |u|) sign(v)) with
//   sign(0) = +1; n = (u, v, z) normalized (error about 0.12 degrees at most).
//
// decodeSplats takes untrusted bytes and never throws for their content: a refusal is
// {ok: false, code, message} with a code of SplatErrorCode. It validates the whole structure
// first, then allocates one Float32Array of positions, one of normals and one Uint8Array of
// colours for every point of the buffer and hands each brick subarray views of them: no
// allocation per point.

export const SPLAT_HEADER_BYTES = 16;
export const SPLAT_BRICK_HEADER_BYTES = 8;
export const SPLAT_POINT_BYTES = 8;
export const SPLAT_PAINTED_POINT_BYTES = 12; // version 2, painted bricks
export const SPLAT_FORMAT_VERSION = 2; // the newest, which clients opt into with `splats: 2`
export const SPLAT_PAINTED_BIT = 0x8000; // version 2, in a block's N
export const SPLAT_COUNT_MASK = 0x03ff; // version 2, in a block's N
// The clay colour (server/engine/channels.hpp kClayColor): the base colour of a session that
// was created without one.
export const CLAY_COLOR = Object.freeze([221, 181, 155]);
export const MAX_POINTS_PER_BRICK = 512;
export const BRICK_SIDE = 8;
// Position quantization: the step between codes and the largest error of a decoded coordinate.
export const POSITION_STEP = 3 / 4096;
export const POSITION_ERROR = POSITION_STEP / 2;

const MAGIC = [0x4d, 0x5a, 0x53, 0x50]; // "MZSP"
const POS_MASK = 0x3fff;
const OCT_MAX = 2047;
const fround = Math.fround;
const STEP = fround(POSITION_STEP);

export const SplatErrorCode = Object.freeze({
  Truncated: "truncated", // the bytes end inside the header, a brick header or a brick's points
  BadMagic: "bad_magic", // bytes 0-3 are not "MZSP"
  BadVersion: "bad_version", // version other than 1 and 2
  BadReserved: "bad_reserved", // the reserved header field is not 0
  CountsTooLarge: "counts_too_large", // B or the point total exceeds what the bytes can hold
  BrickTooLarge: "brick_too_large", // a brick claims more than 512 points
  BadBrickWord: "bad_brick_word", // version 2: N's bits 10..14 set, or painted without points
  TrailingBytes: "trailing_bytes", // bytes after the last brick block
  PointCountMismatch: "point_count_mismatch", // the header's total differs from the blocks' sum
  RepeatedBrick: "repeated_brick", // a brick listed twice
});

function asBytes(data) {
  if (data instanceof Uint8Array) return data;
  if (data instanceof ArrayBuffer) return new Uint8Array(data);
  if (ArrayBuffer.isView(data)) return new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  throw new TypeError("expected an ArrayBuffer or an ArrayBuffer view");
}

function refuse(code, message) {
  return { ok: false, code, message };
}

function sign(x) {
  return x < 0 ? -1 : 1;
}

// A block's N in `version`: {n, painted, code} with code null when N is one that version writes.
function readCount(word, version) {
  if (version === 1) return { n: word, painted: false, code: word > MAX_POINTS_PER_BRICK ? SplatErrorCode.BrickTooLarge : null };
  const n = word & SPLAT_COUNT_MASK;
  const painted = (word & SPLAT_PAINTED_BIT) !== 0;
  let code = null;
  if ((word & ~(SPLAT_COUNT_MASK | SPLAT_PAINTED_BIT)) !== 0 || (painted && n === 0)) code = SplatErrorCode.BadBrickWord;
  else if (n > MAX_POINTS_PER_BRICK) code = SplatErrorCode.BrickTooLarge;
  return { n, painted, code };
}

// Decodes a whole splat buffer. Checks, in the order of the C++ decoder: header length, magic,
// version, reserved field, counts against the byte length, then per block its header, its N
// and its points, then trailing bytes, the point total and repeated bricks.
// Result: {ok: true, version, pointCount, positions, normals, colors, bricks: [{brick: [x, y, z],
// count, painted, positions, normals, colors}]} where positions and normals hold x, y, z per
// point (3 * count floats), colors r, g, b, mask per point (4 * count bytes; an unpainted
// brick's points, and every point of version 1, take `baseColor` with mask 0), and each brick's
// arrays are views into the buffer-wide ones, in buffer order.
// Throws only a TypeError when `data` is not binary data at all (a programming error).
export function decodeSplats(data, { baseColor = CLAY_COLOR } = {}) {
  const bytes = asBytes(data);
  const size = bytes.length;
  if (size < SPLAT_HEADER_BYTES)
    return refuse(SplatErrorCode.Truncated, `truncated: ${size} bytes, the header alone takes 16`);
  if (MAGIC.some((m, i) => bytes[i] !== m))
    return refuse(SplatErrorCode.BadMagic, "not a splat buffer (wrong magic bytes)");
  const view = new DataView(bytes.buffer, bytes.byteOffset, size);
  const version = view.getUint16(4, true);
  if (version !== 1 && version !== 2)
    return refuse(SplatErrorCode.BadVersion, `unsupported version ${version} (this decoder reads versions 1 and 2)`);
  if (view.getUint16(6, true) !== 0) return refuse(SplatErrorCode.BadReserved, "reserved header bytes must be 0");
  const brickCount = view.getUint32(8, true);
  const pointCount = view.getUint32(12, true);
  const room = Math.floor((size - SPLAT_HEADER_BYTES) / SPLAT_BRICK_HEADER_BYTES);
  if (brickCount > room || pointCount > room)
    return refuse(
      SplatErrorCode.CountsTooLarge,
      `counts (${brickCount} bricks, ${pointCount} points) exceed what ${size} bytes can hold`,
    );

  // Pass 1: the structure, reading brick headers only.
  const seen = new Set();
  let repeated = false;
  let at = SPLAT_HEADER_BYTES;
  let points = 0;
  for (let i = 0; i < brickCount; ++i) {
    if (size - at < SPLAT_BRICK_HEADER_BYTES)
      return refuse(SplatErrorCode.Truncated, `truncated in the header of brick block ${i}`);
    const key = view.getUint16(at, true) + 65536 * (view.getUint16(at + 2, true) + 65536 * view.getUint16(at + 4, true));
    const word = view.getUint16(at + 6, true);
    const { n, painted, code } = readCount(word, version);
    at += SPLAT_BRICK_HEADER_BYTES;
    if (code === SplatErrorCode.BrickTooLarge)
      return refuse(code, `brick block ${i} claims ${n} points (at most 512)`);
    if (code)
      return refuse(code, `brick block ${i} has N = ${word} (bits 10..14 must be 0, a painted brick has points)`);
    const pointBytes = painted ? SPLAT_PAINTED_POINT_BYTES : SPLAT_POINT_BYTES;
    if (Math.floor((size - at) / pointBytes) < n)
      return refuse(SplatErrorCode.Truncated, `truncated in the points of brick block ${i}`);
    at += n * pointBytes;
    points += n;
    if (seen.has(key)) repeated = true;
    seen.add(key);
  }
  if (at !== size)
    return refuse(SplatErrorCode.TrailingBytes, `${size - at} trailing bytes after the last brick block`);
  if (points !== pointCount)
    return refuse(
      SplatErrorCode.PointCountMismatch,
      `the header announces ${pointCount} points, the blocks hold ${points}`,
    );
  if (repeated) return refuse(SplatErrorCode.RepeatedBrick, "a brick is listed twice");

  // Pass 2: the points.
  const positions = new Float32Array(3 * pointCount);
  const normals = new Float32Array(3 * pointCount);
  const colors = new Uint8Array(4 * pointCount);
  const bricks = new Array(brickCount);
  const [br, bg, bb] = baseColor;
  at = SPLAT_HEADER_BYTES;
  let out = 0;
  for (let i = 0; i < brickCount; ++i) {
    const bx = view.getUint16(at, true);
    const by = view.getUint16(at + 2, true);
    const bz = view.getUint16(at + 4, true);
    const { n, painted } = readCount(view.getUint16(at + 6, true), version);
    const pointBytes = painted ? SPLAT_PAINTED_POINT_BYTES : SPLAT_POINT_BYTES;
    at += SPLAT_BRICK_HEADER_BYTES;
    const ox = BRICK_SIDE * bx - 2;
    const oy = BRICK_SIDE * by - 2;
    const oz = BRICK_SIDE * bz - 2;
    const first = out;
    for (let k = 0; k < n; ++k, at += pointBytes, out += 3) {
      const lo = view.getUint32(at, true);
      const hi = view.getUint32(at + 4, true);
      positions[out] = ox + (lo & POS_MASK) * STEP;
      positions[out + 1] = oy + ((lo >>> 14) & POS_MASK) * STEP;
      positions[out + 2] = oz + ((lo >>> 28) | ((hi & 0x3ff) << 4)) * STEP;
      let u = fround((2 * ((hi >>> 10) & 0x7ff) - OCT_MAX) / OCT_MAX);
      let v = fround((2 * (hi >>> 21) - OCT_MAX) / OCT_MAX);
      const z = fround(fround(1 - Math.abs(u)) - Math.abs(v));
      if (z < 0) {
        const fu = fround(fround(1 - Math.abs(v)) * sign(u));
        v = fround(fround(1 - Math.abs(u)) * sign(v));
        u = fu;
      }
      const inv = fround(1 / fround(Math.sqrt(fround(fround(fround(u * u) + fround(v * v)) + fround(z * z)))));
      normals[out] = u * inv;
      normals[out + 1] = v * inv;
      normals[out + 2] = z * inv;
      const c = (out / 3) * 4;
      if (painted) {
        colors[c] = bytes[at + 8];
        colors[c + 1] = bytes[at + 9];
        colors[c + 2] = bytes[at + 10];
        colors[c + 3] = bytes[at + 11];
      } else {
        colors[c] = br;
        colors[c + 1] = bg;
        colors[c + 2] = bb;
      }
    }
    bricks[i] = {
      brick: [bx, by, bz],
      count: n,
      painted,
      positions: positions.subarray(first, out),
      normals: normals.subarray(first, out),
      colors: colors.subarray((first / 3) * 4, (out / 3) * 4),
    };
  }
  return { ok: true, version, pointCount, positions, normals, colors, bricks };
}
