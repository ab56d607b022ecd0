// protocol/js/splats.js: the splat payloads of the golden vectors, round trips through an
// encoder written here from the description in protocol/cpp/splats.hpp, and every refusal.
import { test } from "node:test";
import assert from "node:assert/strict";

import { FrameKind, decodeFrame } from "../../../protocol/js/frames.js";
import {
  BRICK_SIDE,
  CLAY_COLOR,
  POSITION_ERROR,
  SPLAT_BRICK_HEADER_BYTES,
  SPLAT_HEADER_BYTES,
  SPLAT_PAINTED_POINT_BYTES,
  SPLAT_POINT_BYTES,
  SplatErrorCode,
  decodeSplats,
} from "../../../protocol/js/splats.js";
import { fromHex, random, vectors } from "./vectors.mjs";

const ERROR_CODES = new Set(Object.values(SplatErrorCode));
// splats.hpp: "error about 0.12 degrees at most" for normals.
const NORMAL_ERROR_DEGREES = 0.125;

// The encoder of splats.hpp: C = round((q - 8 * brick + 2) * 16384 / 12) clamped to [0, 16383];
// n projected onto the octahedron, the lower half folded, (x + 1) * 2047 / 2 rounded and clamped.
// Version 2: a brick with `texels` ([r, g, b, mask] per point) is painted, its points 12 bytes;
// `word` overrides a block's N.
function encodeSplats(bricks, { version = 1, reserved = 0, brickCount, pointCount } = {}) {
  const total = bricks.reduce((s, b) => s + b.points.length, 0);
  const paintedPoints = bricks.reduce((s, b) => s + (b.texels ? b.points.length : 0), 0);
  const out = new Uint8Array(
    SPLAT_HEADER_BYTES +
      bricks.length * SPLAT_BRICK_HEADER_BYTES +
      total * SPLAT_POINT_BYTES +
      paintedPoints * (SPLAT_PAINTED_POINT_BYTES - SPLAT_POINT_BYTES),
  );
  const view = new DataView(out.buffer);
  out.set([0x4d, 0x5a, 0x53, 0x50]);
  view.setUint16(4, version, true);
  view.setUint16(6, reserved, true);
  view.setUint32(8, brickCount ?? bricks.length, true);
  view.setUint32(12, pointCount ?? total, true);
  const sign = (x) => (x < 0 ? -1 : 1);
  const posCode = (q, brick) =>
    Math.min(16383, Math.max(0, Math.round((q - BRICK_SIDE * brick + 2) * (16384 / 12))));
  const octCode = (c) => Math.min(2047, Math.max(0, Math.round(((c + 1) * 2047) / 2)));
  let at = SPLAT_HEADER_BYTES;
  for (const { brick, points, count, texels, word } of bricks) {
    brick.forEach((c, i) => view.setUint16(at + 2 * i, c, true));
    view.setUint16(at + 6, word ?? (count ?? points.length) | (texels ? 0x8000 : 0), true);
    at += SPLAT_BRICK_HEADER_BYTES;
    for (const [k, [x, y, z, nx, ny, nz]] of points.entries()) {
      const l1 = Math.abs(nx) + Math.abs(ny) + Math.abs(nz);
      let u = nx / l1;
      let v = ny / l1;
      if (nz < 0) [u, v] = [(1 - Math.abs(v)) * sign(u), (1 - Math.abs(u)) * sign(v)];
      const X = posCode(x, brick[0]);
      const Y = posCode(y, brick[1]);
      const Z = posCode(z, brick[2]);
      const U = octCode(u);
      const V = octCode(v);
      view.setUint32(at, (X | (Y << 14) | (Z << 28)) >>> 0, true);
      view.setUint32(at + 4, ((Z >>> 4) | (U << 10) | (V << 21)) >>> 0, true);
      at += SPLAT_POINT_BYTES;
      if (texels) {
        out.set(texels[k], at);
        at += SPLAT_PAINTED_POINT_BYTES - SPLAT_POINT_BYTES;
      }
    }
  }
  return out;
}

function errorOf(bytes) {
  const r = decodeSplats(bytes);
  assert.equal(r.ok, false);
  assert.ok(ERROR_CODES.has(r.code), `unknown code ${r.code}`);
  assert.ok(typeof r.message === "string" && r.message.length > 0);
  return r.code;
}

function angleDegrees(a, b) {
  const dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return (Math.acos(Math.min(1, dot)) * 180) / Math.PI;
}

function checkDecodedGeometry(r) {
  let counted = 0;
  for (const b of r.bricks) {
    assert.equal(b.positions.length, 3 * b.count);
    assert.equal(b.normals.length, 3 * b.count);
    for (let k = 0; k < 3 * b.count; k += 3) {
      for (let a = 0; a < 3; ++a) {
        const lo = BRICK_SIDE * b.brick[a] - 2;
        assert.ok(b.positions[k + a] >= lo && b.positions[k + a] < lo + 12, "position inside the brick's range");
      }
      const n = b.normals.subarray(k, k + 3);
      assert.ok(Math.abs(Math.hypot(n[0], n[1], n[2]) - 1) < 1e-6, "unit normal");
    }
    counted += b.count;
  }
  assert.equal(counted, r.pointCount);
  assert.equal(r.positions.length, 3 * r.pointCount);
  assert.equal(r.normals.length, 3 * r.pointCount);
}

test("the splat payloads of the vectors decode, counts as their size says", () => {
  let seen = 0;
  for (const v of vectors.binary) {
    if (v.header.kind !== FrameKind.SplatsFull && v.header.kind !== FrameKind.SplatsDelta) continue;
    const frame = decodeFrame(fromHex(v.hex));
    assert.equal(frame.ok, true, v.name);
    const r = decodeSplats(frame.payload);
    assert.equal(r.ok, true, `${v.name}: ${r.message}`);
    assert.equal(r.version, 1);
    // The size of a splat buffer is 16 + 8 B + 8 P: the counts must account for every byte.
    assert.equal(
      SPLAT_HEADER_BYTES + SPLAT_BRICK_HEADER_BYTES * r.bricks.length + SPLAT_POINT_BYTES * r.pointCount,
      v.header.payload_length,
      v.name,
    );
    assert.deepEqual(decodeSplats(fromHex(v.payload_hex)), r, v.name);
    checkDecodedGeometry(r);
    ++seen;
  }
  assert.ok(seen >= 2);
});

test("points round-trip within the documented quantization", () => {
  const next = random(7);
  const bricks = [];
  const expected = [];
  for (let b = 0; b < 20; ++b) {
    // Coordinates of grids up to 512 vu, where float32 still resolves the 3/4096 vu steps.
    const brick = [b, 3 * b + 1, 63 - b];
    const points = [];
    const count = b === 5 ? 0 : b === 6 ? 512 : 1 + Math.floor(next() * 40);
    for (let k = 0; k < count; ++k) {
      const q = brick.map((c) => BRICK_SIDE * c - 2 + next() * 11.99);
      let n = [next() * 2 - 1, next() * 2 - 1, next() * 2 - 1];
      if (k === 0) n = [0, 0, -1];
      if (k === 1) n = [1, 0, 0];
      if (k === 2) n = [0, -1, 0];
      const len = Math.hypot(...n) || 1;
      n = n.map((c) => c / len);
      points.push([...q, ...n]);
    }
    bricks.push({ brick, points });
    expected.push(points);
  }
  const r = decodeSplats(encodeSplats(bricks));
  assert.equal(r.ok, true, r.message);
  checkDecodedGeometry(r);
  assert.equal(r.bricks.length, bricks.length);
  let worstAngle = 0;
  r.bricks.forEach((b, i) => {
    assert.deepEqual(b.brick, bricks[i].brick);
    assert.equal(b.count, expected[i].length);
    expected[i].forEach((p, k) => {
      for (let a = 0; a < 3; ++a) assert.ok(Math.abs(b.positions[3 * k + a] - p[a]) <= POSITION_ERROR + 1e-6);
      worstAngle = Math.max(worstAngle, angleDegrees(b.normals.subarray(3 * k, 3 * k + 3), p.slice(3)));
    });
  });
  assert.ok(worstAngle <= NORMAL_ERROR_DEGREES, `normal error ${worstAngle} degrees`);
});

test("codes at the ends of their ranges decode to the documented values", () => {
  // A brick at the origin, positions at codes 0 and 16383 (-2 and 10 - 3/4096 vu), normals +z,
  // +x and -z (the folded seam; 2047 codes per axis have no exact middle, hence the angles).
  const bytes = encodeSplats([
    {
      brick: [0, 0, 0],
      points: [
        [-2, -2, -2, 0, 0, 1],
        [10, 10, 10, 1, 0, 0],
        [0, 4, 8, 0, 0, -1],
      ],
    },
  ]);
  const r = decodeSplats(bytes);
  assert.equal(r.ok, true);
  assert.deepEqual(Array.from(r.positions.subarray(0, 6)), [-2, -2, -2, 10 - 3 / 4096, 10 - 3 / 4096, 10 - 3 / 4096]);
  assert.ok(angleDegrees(r.normals.subarray(0, 3), [0, 0, 1]) < NORMAL_ERROR_DEGREES);
  assert.ok(angleDegrees(r.normals.subarray(3, 6), [1, 0, 0]) < NORMAL_ERROR_DEGREES);
  assert.ok(angleDegrees(r.normals.subarray(6, 9), [0, 0, -1]) < NORMAL_ERROR_DEGREES);
});

test("brick arrays are views of the buffer-wide arrays, in buffer order", () => {
  const r = decodeSplats(
    encodeSplats([
      { brick: [1, 1, 1], points: [[9, 9, 9, 0, 1, 0]] },
      { brick: [2, 2, 2], points: [] },
      { brick: [3, 3, 3], points: [[25, 25, 25, 0, 0, 1], [26, 26, 26, 0, 0, 1]] },
    ]),
  );
  assert.equal(r.ok, true);
  assert.deepEqual(r.bricks.map((b) => b.count), [1, 0, 2]);
  assert.equal(r.bricks[2].positions.buffer, r.positions.buffer);
  assert.equal(r.bricks[2].positions.byteOffset, 3 * Float32Array.BYTES_PER_ELEMENT);
  assert.equal(r.bricks[1].positions.length, 0);
});

test("invalid splat buffers are refused with their error", () => {
  const two = [
    { brick: [1, 2, 3], points: [[9, 17, 25, 0, 0, 1]] },
    { brick: [4, 5, 6], points: [[33, 41, 49, 1, 0, 0], [34, 42, 50, 0, 1, 0]] },
  ];
  const good = encodeSplats(two);
  assert.equal(decodeSplats(good).ok, true);
  const withByte = (offset, value) => {
    const b = good.slice();
    b[offset] = value;
    return b;
  };
  const cases = [
    ["empty", new Uint8Array(0), SplatErrorCode.Truncated],
    ["15 bytes", good.subarray(0, 15), SplatErrorCode.Truncated],
    ["magic MZSX", withByte(3, 0x58), SplatErrorCode.BadMagic],
    ["a frame header's magic", withByte(2, 0x50), SplatErrorCode.BadMagic],
    ["version 3", withByte(4, 3), SplatErrorCode.BadVersion],
    ["version 0", withByte(4, 0), SplatErrorCode.BadVersion],
    ["reserved 1", withByte(6, 1), SplatErrorCode.BadReserved],
    ["brick count 2^32-1", encodeSplats(two, { brickCount: 0xffffffff }), SplatErrorCode.CountsTooLarge],
    ["point count 2^32-1", encodeSplats(two, { pointCount: 0xffffffff }), SplatErrorCode.CountsTooLarge],
    ["a brick of 513 points", encodeSplats([{ brick: [0, 0, 0], points: [], count: 513 }], { pointCount: 0 }), SplatErrorCode.BrickTooLarge],
    ["one brick block more than the bytes", encodeSplats(two, { brickCount: 3 }), SplatErrorCode.Truncated],
    ["more points than the bytes", encodeSplats([{ brick: [0, 0, 0], points: [[1, 1, 1, 0, 0, 1]], count: 2 }]), SplatErrorCode.Truncated],
    ["one byte too many", Uint8Array.of(...good, 0), SplatErrorCode.TrailingBytes],
    ["one brick block fewer than the bytes", encodeSplats(two, { brickCount: 1 }), SplatErrorCode.TrailingBytes],
    ["point total too small", encodeSplats(two, { pointCount: 2 }), SplatErrorCode.PointCountMismatch],
    ["point total too large", encodeSplats(two, { pointCount: 4 }), SplatErrorCode.PointCountMismatch],
    [
      "a brick listed twice",
      encodeSplats([two[0], two[1], { brick: [1, 2, 3], points: [] }]),
      SplatErrorCode.RepeatedBrick,
    ],
  ];
  for (const [name, bytes, code] of cases) assert.equal(errorOf(bytes), code, name);
  // Bricks differing in one coordinate only are distinct.
  const distinct = encodeSplats([{ brick: [1, 2, 3], points: [] }, { brick: [3, 2, 1], points: [] }, { brick: [1, 3, 2], points: [] }]);
  assert.equal(decodeSplats(distinct).ok, true);
});

test("every proper prefix of a valid buffer is refused, never thrown", () => {
  const bytes = encodeSplats([
    { brick: [0, 0, 0], points: [[1, 2, 3, 0, 0, 1], [2, 3, 4, 0, 1, 0]] },
    { brick: [0, 0, 1], points: [] },
    { brick: [0, 1, 0], points: [[3, 9, 4, -1, 0, 0]] },
  ]);
  for (let n = 0; n < bytes.length; ++n) {
    const code = errorOf(bytes.subarray(0, n));
    assert.ok(code === SplatErrorCode.Truncated || code === SplatErrorCode.CountsTooLarge, `first ${n} bytes: ${code}`);
  }
});

test("random damage never throws", () => {
  const next = random(3);
  const base = encodeSplats([
    { brick: [2, 2, 2], points: [[17, 17, 17, 0, 0, 1], [18, 18, 18, 0, 1, 0]] },
    { brick: [2, 2, 3], points: [[17, 17, 25, 1, 0, 0]] },
  ]);
  for (let trial = 0; trial < 5000; ++trial) {
    const bytes = base.slice(0, Math.floor(next() * (base.length + 9)));
    for (let f = 0; f < 3 && bytes.length; ++f) bytes[Math.floor(next() * bytes.length)] = Math.floor(next() * 256);
    const r = decodeSplats(bytes);
    if (r.ok) checkDecodedGeometry(r);
    else assert.ok(ERROR_CODES.has(r.code));
  }
  assert.throws(() => decodeSplats([1, 2, 3]), TypeError);
});

// The buffer of tests/engine/test_splats.cpp's kGoldenV2, which the C++ encoder writes: brick
// (1, 2, 3) painted, its point at (9, 17, 25) facing +z in (200, 20, 10) under mask 255; brick
// (0, 0, 0) unpainted, its point at (-2, -2, 4) facing -z.
const GOLDEN_V2 = Uint8Array.of(
  0x4d, 0x5a, 0x53, 0x50, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00,
  0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x80,
  0x00, 0x10, 0x00, 0x04, 0x00, 0x01, 0x10, 0x80, 0xc8, 0x14, 0x0a, 0xff,
  0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00,
  0x00, 0x00, 0x00, 0x00, 0x00, 0xfe, 0xff, 0xff,
);

test("version 2: painted bricks carry their texels, unpainted ones the base colour", () => {
  const r = decodeSplats(GOLDEN_V2, { baseColor: [10, 20, 30] });
  assert.equal(r.ok, true, r.message);
  assert.equal(r.version, 2);
  assert.deepEqual(r.bricks.map((b) => b.painted), [true, false]);
  assert.deepEqual(Array.from(r.positions), [9, 17, 25, -2, -2, 4]);
  assert.deepEqual(Array.from(r.colors), [200, 20, 10, 255, 10, 20, 30, 0]);
  assert.deepEqual(Array.from(r.bricks[1].colors), [10, 20, 30, 0]);
  assert.ok(angleDegrees(r.normals.subarray(0, 3), [0, 0, 1]) < NORMAL_ERROR_DEGREES);
  assert.ok(angleDegrees(r.normals.subarray(3, 6), [0, 0, -1]) < NORMAL_ERROR_DEGREES);
  // The encoder written here from the description gives those bytes.
  const again = encodeSplats(
    [
      { brick: [1, 2, 3], points: [[9, 17, 25, 0, 0, 1]], texels: [[200, 20, 10, 255]] },
      { brick: [0, 0, 0], points: [[-2, -2, 4, 0, 0, -1]] },
    ],
    { version: 2 },
  );
  assert.deepEqual(again, GOLDEN_V2);
  // Without a base colour: the clay; version 1 points take it too.
  assert.deepEqual(Array.from(decodeSplats(GOLDEN_V2).bricks[1].colors), [...CLAY_COLOR, 0]);
  const v1 = decodeSplats(encodeSplats([{ brick: [0, 0, 0], points: [[1, 2, 3, 0, 0, 1]] }]), { baseColor: [1, 2, 3] });
  assert.deepEqual(Array.from(v1.colors), [1, 2, 3, 0]);
  assert.equal(v1.bricks[0].painted, false);
});

test("version 2: inconsistent brick words and lengths are refused", () => {
  const withByte = (offset, value) => {
    const b = GOLDEN_V2.slice();
    b[offset] = value;
    return b;
  };
  for (let bit = 10; bit <= 14; ++bit) {
    for (const block of [16, 36]) {
      const b = GOLDEN_V2.slice();
      b[block + 7] |= 1 << (bit - 8);
      assert.equal(errorOf(b), SplatErrorCode.BadBrickWord, `block at ${block}, bit ${bit}`);
    }
  }
  const paintedEmpty = encodeSplats([{ brick: [0, 0, 0], points: [], word: 0x8000 }], { version: 2 });
  assert.equal(errorOf(paintedEmpty), SplatErrorCode.BadBrickWord);
  assert.equal(errorOf(withByte(16 + 7, 0x82)), SplatErrorCode.BrickTooLarge); // 513 | painted
  assert.equal(errorOf(withByte(16 + 7, 0x00)), SplatErrorCode.TrailingBytes); // 8-byte points: 4 bytes over
  assert.equal(errorOf(withByte(36 + 7, 0x80)), SplatErrorCode.Truncated); // 12-byte points: 4 bytes short
  // Version 1 has no flag: 0x8001 is 32769 points.
  const v1 = GOLDEN_V2.slice();
  v1[4] = 1;
  assert.equal(errorOf(v1), SplatErrorCode.BrickTooLarge);
  for (let n = 0; n < GOLDEN_V2.length; ++n) {
    const code = errorOf(GOLDEN_V2.subarray(0, n));
    assert.ok(code === SplatErrorCode.Truncated || code === SplatErrorCode.CountsTooLarge, `first ${n} bytes: ${code}`);
  }
});
