// protocol/js/frames.js against the golden vectors and the checks of protocol/cpp/frames.cpp
// (tests/protocol/test_frames.cpp does the same for C++).
import { test } from "node:test";
import assert from "node:assert/strict";

import {
  FRAME_HEADER_BYTES,
  FrameErrorCode,
  FrameKind,
  decodeFrame,
  encodeFrame,
  frameKindName,
  isFrameKind,
} from "../../../protocol/js/frames.js";
import { fromHex, random, vectors } from "./vectors.mjs";

const ERROR_CODES = new Set(Object.values(FrameErrorCode));

function errorOf(bytes, options) {
  const r = decodeFrame(bytes, options);
  assert.equal(r.ok, false);
  assert.ok(ERROR_CODES.has(r.code), `unknown code ${r.code}`);
  assert.ok(typeof r.message === "string" && r.message.length > 0);
  return r.code;
}

test("every binary vector decodes to its fields and re-encodes to the same bytes", () => {
  const kinds = new Set();
  assert.ok(vectors.binary.length >= 9);
  for (const v of vectors.binary) {
    const bytes = fromHex(v.hex);
    const r = decodeFrame(bytes);
    assert.equal(r.ok, true, v.name);
    const h = r.header;
    const want = v.header;
    assert.equal(h.version, want.version, v.name);
    assert.equal(h.kind, want.kind, v.name);
    assert.equal(frameKindName(h.kind), want.kind_name, v.name);
    assert.equal(h.requestId, want.request_id, v.name);
    assert.equal(typeof h.revision, "bigint");
    assert.equal(h.revision, BigInt(want.revision), v.name);
    assert.equal(h.revision.toString(), want.revision, v.name);
    assert.equal(h.payloadLength, want.payload_length, v.name);
    const payload = fromHex(v.payload_hex);
    assert.deepEqual(r.payload, payload, v.name);
    assert.equal(r.payload.buffer, bytes.buffer, "the payload is a view, not a copy");
    assert.deepEqual(encodeFrame(h.kind, h.requestId, h.revision, payload), bytes, v.name);
    kinds.add(h.kind);
  }
  assert.equal(kinds.size, 11);
});

test("ArrayBuffers and views at an offset decode alike", () => {
  for (const v of vectors.binary) {
    const bytes = fromHex(v.hex);
    const fromBuffer = decodeFrame(bytes.slice().buffer);
    const padded = new Uint8Array(bytes.length + 5);
    padded.set(bytes, 3);
    const fromView = decodeFrame(padded.subarray(3, 3 + bytes.length));
    const fromDataView = decodeFrame(new DataView(padded.buffer, 3, bytes.length));
    for (const r of [fromBuffer, fromView, fromDataView]) {
      assert.equal(r.ok, true, v.name);
      assert.equal(r.header.revision, BigInt(v.header.revision), v.name);
      assert.deepEqual(r.payload, fromHex(v.payload_hex), v.name);
    }
  }
  assert.throws(() => decodeFrame("MZPN"), TypeError);
});

test("FrameKind names the kinds of the vectors", () => {
  const camel = (name) => name.replace(/(^|_)([a-z])/g, (_, __, c) => c.toUpperCase());
  for (const v of vectors.binary) assert.equal(FrameKind[camel(v.header.kind_name)], v.header.kind, v.name);
  assert.deepEqual(
    Object.values(FrameKind),
    [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
  );
  for (const k of [0, 12, 65535, 1.5, -1, NaN]) {
    assert.equal(isFrameKind(k), false);
    assert.equal(frameKindName(k), "");
  }
});

test("every invalid binary vector is refused with its error", () => {
  assert.ok(vectors.binary_invalid.length > 0);
  for (const v of vectors.binary_invalid) {
    const options = "max_payload" in v ? { maxPayload: v.max_payload } : undefined;
    assert.equal(errorOf(fromHex(v.hex), options), v.error, v.name);
  }
});

test("every truncated prefix of a valid frame is refused", () => {
  // The decoder's order (PROTOCOL.md, "Binary frames"): a prefix shorter than the header is a
  // short header; a longer one has an intact header whose length no longer matches. The
  // vectors "23 bytes" and "one payload byte missing" pin one of each.
  const expected = (n) => (n < FRAME_HEADER_BYTES ? FrameErrorCode.ShortHeader : FrameErrorCode.LengthMismatch);
  for (const v of vectors.binary_invalid)
    if (v.name === "23 bytes" || v.name === "one payload byte missing")
      assert.equal(expected(fromHex(v.hex).length), v.error, v.name);
  for (const v of vectors.binary) {
    const bytes = fromHex(v.hex);
    for (let n = 0; n < bytes.length; ++n)
      assert.equal(errorOf(bytes.subarray(0, n)), expected(n), `${v.name}, first ${n} bytes`);
  }
});

test("encoding writes every field little-endian at its offset", () => {
  const payload = new Uint8Array([1, 2, 3]);
  const bytes = encodeFrame(FrameKind.MeshPly, 0xa1b2c3d4, 0x1122334455667788n, payload);
  const want = [
    0x4d, 0x5a, 0x50, 0x4e, 1, 0, 7, 0, 0xd4, 0xc3, 0xb2, 0xa1, 0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11, 3, 0, 0,
    0, 1, 2, 3,
  ];
  assert.deepEqual(bytes, new Uint8Array(want));
  const r = decodeFrame(bytes, { maxPayload: 3 });
  assert.equal(r.ok, true);
  assert.deepEqual(r.header, {
    version: 1,
    kind: FrameKind.MeshPly,
    requestId: 0xa1b2c3d4,
    revision: 0x1122334455667788n,
    payloadLength: 3,
  });
  assert.equal(r.payload.byteOffset, FRAME_HEADER_BYTES);
  assert.equal(errorOf(bytes, { maxPayload: 2 }), FrameErrorCode.TooLarge);
  assert.deepEqual(encodeFrame(FrameKind.FrameJpeg, 5, 6, payload), encodeFrame(FrameKind.FrameJpeg, 5, 6n, payload));
  assert.deepEqual(encodeFrame(FrameKind.VolumeUpload, 1, 0), encodeFrame(FrameKind.VolumeUpload, 1, 0n, new Uint8Array(0)));
});

test("encoding refuses values the header cannot carry", () => {
  const payload = new Uint8Array([1]);
  for (const kind of [0, 12, 1.5, "1"]) assert.throws(() => encodeFrame(kind, 1, 1n, payload), RangeError);
  for (const id of [-1, 2 ** 32, 0.5, NaN]) assert.throws(() => encodeFrame(FrameKind.MeshStl, id, 1n, payload), RangeError);
  for (const rev of [-1n, 1n << 64n, -1, 2 ** 53, 0.5])
    assert.throws(() => encodeFrame(FrameKind.MeshStl, 1, rev, payload), RangeError);
  assert.equal(decodeFrame(encodeFrame(FrameKind.MeshStl, 2 ** 32 - 1, (1n << 64n) - 1n, payload)).ok, true);
});

test("every single-byte change to a header field is caught or decoded as that field", () => {
  const good = encodeFrame(FrameKind.FrameJpeg, 5, 6n, new Uint8Array([9, 8, 7, 6]));
  for (let i = 0; i < FRAME_HEADER_BYTES; ++i) {
    for (const value of [0x00, 0x01, 0x0a, 0xff]) {
      if (good[i] === value) continue;
      const bytes = good.slice();
      bytes[i] = value;
      const what = `byte ${i} set to ${value}`;
      const r = decodeFrame(bytes);
      if (i < 4) assert.equal(errorOf(bytes), FrameErrorCode.BadMagic, what);
      else if (i < 6) assert.equal(errorOf(bytes), FrameErrorCode.BadVersion, what);
      else if (i < 8) assert.equal(r.ok, isFrameKind(bytes[6] | (bytes[7] << 8)), what);
      else if (i < 20) assert.equal(r.ok, true, what);
      else assert.equal(errorOf(bytes), FrameErrorCode.LengthMismatch, what);
    }
  }
});

test("random bytes never throw", () => {
  const next = random(1);
  const base = fromHex(vectors.binary[1].hex);
  for (let trial = 0; trial < 5000; ++trial) {
    const bytes = trial % 2 ? base.slice(0, Math.floor(next() * (base.length + 8))) : base.slice();
    const flips = 1 + Math.floor(next() * 4);
    for (let f = 0; f < flips && bytes.length; ++f) bytes[Math.floor(next() * bytes.length)] = Math.floor(next() * 256);
    const r = decodeFrame(bytes, { maxPayload: Math.floor(next() * 64) });
    if (!r.ok) assert.ok(ERROR_CODES.has(r.code));
    else assert.equal(r.payload.length, r.header.payloadLength);
  }
});
