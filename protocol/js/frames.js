// Binary frames: the fixed 24-byte header in front of every binary WebSocket message.
// protocol/PROTOCOL.md, section "Binary frames", is the contract; protocol/cpp/frames.cpp is the
// C++ side, which this module mirrors check for check and error code for error code.
//
// Conventions: every integer little-endian; byte offsets from the frame start:
//    0  4  magic "MZPN"       4  2  u16 format version (1)   6  2  u16 kind (FrameKind)
//    8  4  u32 request id     12 8  u64 session revision     20 4  u32 payload length
//   24  ... payload, exactly `payload length` bytes, nothing after it.
// The revision is a BigInt (u64 does not fit a Number). decodeFrame takes untrusted bytes: it
// never throws for their content, never copies the payload and reports every refusal as
// {ok: false, code, message} with a code of FrameErrorCode.

export const FRAME_HEADER_BYTES = 24;
export const FRAME_FORMAT_VERSION = 1;
// The largest payload the header can describe; callers pass their own, smaller limit.
export const MAX_FRAME_PAYLOAD = 0xffffffff;

const MAGIC = [0x4d, 0x5a, 0x50, 0x4e]; // "MZPN"
const VERSION_OFFSET = 4;
const KIND_OFFSET = 6;
const REQUEST_ID_OFFSET = 8;
const REVISION_OFFSET = 12;
const LENGTH_OFFSET = 20;
const MAX_U64 = (1n << 64n) - 1n;

export const FrameKind = Object.freeze({
  SplatsFull: 1, // server -> client: every brick with points (splats.js buffer)
  SplatsDelta: 2, // server -> client: the listed bricks replace their old points
  FrameJpeg: 3, // server -> client: a ray-cast image, JPEG file
  FramePng: 4, // server -> client: a ray-cast image, PNG file
  MeshStl: 5, // server -> client: binary STL
  MeshObj: 6, // server -> client: Wavefront OBJ text
  MeshPly: 7, // server -> client: binary little-endian PLY
  VolumeFile: 8, // server -> client: a .mzv file
  VolumeUpload: 9, // client -> server: the file (.mzv or .vdb) for the volume.load request it names
  MeshGlb: 10, // server -> client: binary glTF 2.0 (.glb)
  VolumeVdb: 11, // server -> client: an OpenVDB level set (.vdb), volume.save {format: "vdb"} (1.3)
});

const KIND_NAMES = [
  "",
  "splats_full",
  "splats_delta",
  "frame_jpeg",
  "frame_png",
  "mesh_stl",
  "mesh_obj",
  "mesh_ply",
  "volume_file",
  "volume_upload",
  "mesh_glb",
  "volume_vdb",
];

// The spelling of the golden vectors (tests/protocol/vectors) and of frameErrorCodeName in C++.
export const FrameErrorCode = Object.freeze({
  ShortHeader: "short_header", // fewer than 24 bytes
  BadMagic: "bad_magic", // bytes 0-3 are not "MZPN"
  BadVersion: "bad_version", // format version other than 1
  BadKind: "bad_kind", // kind outside 1..11
  TooLarge: "too_large", // declared payload length above the caller's limit
  LengthMismatch: "length_mismatch", // declared payload length differs from the bytes after the header
});

// True for the values of FrameKind.
export function isFrameKind(value) {
  return Number.isInteger(value) && value >= 1 && value <= 11;
}

// "splats_full", "splats_delta", ..., "volume_upload"; "" for other values.
export function frameKindName(kind) {
  return isFrameKind(kind) ? KIND_NAMES[kind] : "";
}

// A Uint8Array over the same memory as an ArrayBuffer or any ArrayBuffer view.
function asBytes(data) {
  if (data instanceof Uint8Array) return data;
  if (data instanceof ArrayBuffer) return new Uint8Array(data);
  if (ArrayBuffer.isView(data)) return new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  throw new TypeError("expected an ArrayBuffer or an ArrayBuffer view");
}

function hexByte(b) {
  return b.toString(16).padStart(2, "0");
}

function refuse(code, message) {
  return { ok: false, code, message };
}

// The header and payload of one whole binary message. Checks, in this order: at least 24
// bytes, magic, version, kind, payload length <= maxPayload, payload length == bytes after the
// header. `payload` is a view into `data`, not a copy. Throws only a TypeError when `data` is
// not binary data at all (a programming error, not bad bytes).
export function decodeFrame(data, { maxPayload = MAX_FRAME_PAYLOAD } = {}) {
  const bytes = asBytes(data);
  if (bytes.length < FRAME_HEADER_BYTES)
    return refuse(
      FrameErrorCode.ShortHeader,
      `binary frame of ${bytes.length} bytes is shorter than its 24-byte header`,
    );
  if (MAGIC.some((m, i) => bytes[i] !== m)) {
    const got = Array.from(bytes.subarray(0, 4), hexByte).join("");
    return refuse(FrameErrorCode.BadMagic, `binary frame magic must be "MZPN" (4d5a504e), got ${got}`);
  }
  const view = new DataView(bytes.buffer, bytes.byteOffset, FRAME_HEADER_BYTES);
  const version = view.getUint16(VERSION_OFFSET, true);
  if (version !== FRAME_FORMAT_VERSION)
    return refuse(
      FrameErrorCode.BadVersion,
      `binary frame format version ${version} is not supported (supported: 1)`,
    );
  const kind = view.getUint16(KIND_OFFSET, true);
  if (!isFrameKind(kind))
    return refuse(FrameErrorCode.BadKind, `binary frame kind ${kind} is unknown (known: 1 to 11)`);
  const requestId = view.getUint32(REQUEST_ID_OFFSET, true);
  const revision = view.getBigUint64(REVISION_OFFSET, true);
  const payloadLength = view.getUint32(LENGTH_OFFSET, true);
  if (payloadLength > maxPayload)
    return refuse(
      FrameErrorCode.TooLarge,
      `binary frame payload of ${payloadLength} bytes is over the limit of ${maxPayload}`,
    );
  const following = bytes.length - FRAME_HEADER_BYTES;
  if (payloadLength !== following)
    return refuse(
      FrameErrorCode.LengthMismatch,
      `binary frame header declares ${payloadLength} payload bytes but ${following} follow`,
    );
  return {
    ok: true,
    header: { version, kind, requestId, revision, payloadLength },
    payload: bytes.subarray(FRAME_HEADER_BYTES),
  };
}

// The header followed by a copy of the payload, as a new Uint8Array. `revision` is a BigInt or a
// non-negative safe integer Number. Throws a RangeError for a kind outside FrameKind, a request
// id outside u32, a revision outside u64 or a payload longer than MAX_FRAME_PAYLOAD.
export function encodeFrame(kind, requestId, revision, payload = new Uint8Array(0)) {
  if (!isFrameKind(kind)) throw new RangeError(`binary frame kind ${kind} is unknown`);
  if (!Number.isInteger(requestId) || requestId < 0 || requestId > 0xffffffff)
    throw new RangeError(`binary frame request id ${requestId} is not a u32`);
  if (typeof revision === "number" && !Number.isSafeInteger(revision))
    throw new RangeError(`binary frame revision ${revision} is not an integer`);
  const rev = BigInt(revision);
  if (rev < 0n || rev > MAX_U64) throw new RangeError(`binary frame revision ${rev} is not a u64`);
  const body = asBytes(payload);
  if (body.length > MAX_FRAME_PAYLOAD)
    throw new RangeError(`binary frame payload of ${body.length} bytes does not fit the 32-bit length field`);
  const out = new Uint8Array(FRAME_HEADER_BYTES + body.length);
  out.set(MAGIC, 0);
  const view = new DataView(out.buffer);
  view.setUint16(VERSION_OFFSET, FRAME_FORMAT_VERSION, true);
  view.setUint16(KIND_OFFSET, kind, true);
  view.setUint32(REQUEST_ID_OFFSET, requestId, true);
  view.setBigUint64(REVISION_OFFSET, rev, true);
  view.setUint32(LENGTH_OFFSET, body.length, true);
  out.set(body, FRAME_HEADER_BYTES);
  return out;
}
