// Splat buffers: the payload of binary frames of kind 1 (splats full) and 2 (splats delta).
// protocol/cpp/splats.hpp specifies the format byte by byte; this decoder mirrors its C++
// decodeSplats check for check, and gives the same float values (each step rounded to float32
// as the C++ code does).
//
// Conventions: integers little-endian; positions in vu of the session grid (voxel (i, j, k) at
// (i, j, k)); normals unit length, outward. Layout:
//   header, 16 bytes: "MZSP", u16 version = 1, u16 reserved = 0, u32 B bricks, u32 total points
//   B blocks: u16 brick x, y, z (voxel / 8), u16 N (0..512; 0 = the brick has no points), then
//   N u64 points: bits 0..13 X, 14..27 Y, 28..41 Z (position codes), 42..52 U, 53..63 V
//   (octahedral normal); nothing after the last block.
//   Position per axis: 8 * brick + C * 3 / 4096 - 2, i.e. [-2, 10) vu around the brick origin,
//   error <= 3.7e-4 vu. Normal: u = (2U - 2047) / 2047, v = (2V - 2047) / 2047,
//   z = 1 - |u| - |v|; where z < 0, (u, v) <- ((1 - |v|) sign(u), (1 - |u|) sign(v)) with
//   sign(0) = +1; n = (u, v, z) normalized (error about 0.12 degrees at most).
//
// decodeSplats takes untrusted bytes and never throws for their content: a refusal is
// {ok: false, code, message} with a code of SplatErrorCode. It validates the whole structure
// first, then allocates one Float32Array of positions and one of normals for every point of the
// buffer and hands each brick subarray views of them: no allocation per point.

export const SPLAT_HEADER_BYTES = 16;
export const SPLAT_BRICK_HEADER_BYTES = 8;
export const SPLAT_POINT_BYTES = 8;
export const SPLAT_FORMAT_VERSION = 1;
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
  BadVersion: "bad_version", // version other than 1
  BadReserved: "bad_reserved", // the reserved header field is not 0
  CountsTooLarge: "counts_too_large", // B or the point total exceeds what the bytes can hold
  BrickTooLarge: "brick_too_large", // a brick claims more than 512 points
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

// Decodes a whole splat buffer. Checks, in the order of the C++ decoder: header length, magic,
// version, reserved field, counts against the byte length, then per block its header, N <= 512
// and its points, then trailing bytes, the point total and repeated bricks.
// Result: {ok: true, version, pointCount, positions, normals, bricks: [{brick: [x, y, z],
// count, positions, normals}]} where positions and normals hold x, y, z per point (3 * count
// floats) and each brick's arrays are views into the buffer-wide ones, in buffer order.
// Throws only a TypeError when `data` is not binary data at all (a programming error).
export function decodeSplats(data) {
  const bytes = asBytes(data);
  const size = bytes.length;
  if (size < SPLAT_HEADER_BYTES)
    return refuse(SplatErrorCode.Truncated, `truncated: ${size} bytes, the header alone takes 16`);
  if (MAGIC.some((m, i) => bytes[i] !== m))
    return refuse(SplatErrorCode.BadMagic, "not a splat buffer (wrong magic bytes)");
  const view = new DataView(bytes.buffer, bytes.byteOffset, size);
  const version = view.getUint16(4, true);
  if (version !== SPLAT_FORMAT_VERSION)
    return refuse(SplatErrorCode.BadVersion, `unsupported version ${version} (this decoder reads version 1)`);
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
    const n = view.getUint16(at + 6, true);
    at += SPLAT_BRICK_HEADER_BYTES;
    if (n > MAX_POINTS_PER_BRICK)
      return refuse(SplatErrorCode.BrickTooLarge, `brick block ${i} claims ${n} points (at most 512)`);
    if (Math.floor((size - at) / SPLAT_POINT_BYTES) < n)
      return refuse(SplatErrorCode.Truncated, `truncated in the points of brick block ${i}`);
    at += n * SPLAT_POINT_BYTES;
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
  const bricks = new Array(brickCount);
  at = SPLAT_HEADER_BYTES;
  let out = 0;
  for (let i = 0; i < brickCount; ++i) {
    const bx = view.getUint16(at, true);
    const by = view.getUint16(at + 2, true);
    const bz = view.getUint16(at + 4, true);
    const n = view.getUint16(at + 6, true);
    at += SPLAT_BRICK_HEADER_BYTES;
    const ox = BRICK_SIDE * bx - 2;
    const oy = BRICK_SIDE * by - 2;
    const oz = BRICK_SIDE * bz - 2;
    const first = out;
    for (let k = 0; k < n; ++k, at += SPLAT_POINT_BYTES, out += 3) {
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
    }
    bricks[i] = {
      brick: [bx, by, bz],
      count: n,
      positions: positions.subarray(first, out),
      normals: normals.subarray(first, out),
    };
  }
  return { ok: true, version, pointCount, positions, normals, bricks };
}
