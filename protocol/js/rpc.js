// JSON-RPC 2.0 text messages as the browser client sends and receives them (protocol/PROTOCOL.md,
// sections "Requests and responses", "Notifications" and "Errors"). Transport-free: functions
// take and return strings; the client's net/ layer owns the WebSocket.
//
// Conventions: one message per text frame, UTF-8 JSON. Request ids that this module makes are
// integers in [1, 2^32 - 1], so every request, including those answered by a binary frame (whose
// header carries the id as a u32), can use them; after 2^32 - 1 they start again at 1.

import { FrameKind } from "./frames.js";

// The protocol version this module speaks ({major, minor} of PROTOCOL.md).
export const PROTOCOL_VERSION = Object.freeze({ major: 1, minor: 7 });

export const MAX_REQUEST_ID = 0xffffffff;

// Every method of PROTOCOL.md, section "Methods".
export const METHODS = Object.freeze([
  "session.create",
  "session.join",
  "session.leave",
  "session.stats",
  "tool.apply",
  "stroke.begin",
  "stroke.dabs",
  "stroke.end",
  "volume.morph",
  "history.undo",
  "history.redo",
  "view.set",
  "render.frame",
  "splats.get",
  "mesh.export",
  "volume.save",
  "volume.load",
  "analysis.thickness",
  "op.cancel",
  "history.list",
  "session.fork",
  "presence",
  "mask.clear",
  "mask.invert",
  "mask.fill",
]);

// The methods whose id travels in a binary frame header (an answer, or volume.load's upload).
export const BINARY_METHODS = Object.freeze([
  "render.frame",
  "splats.get",
  "mesh.export",
  "volume.save",
  "volume.load",
]);

// Error codes of PROTOCOL.md, section "Errors". Branch on these and on error.data, never on
// error.message.
export const RpcErrorCode = Object.freeze({
  ParseError: -32700,
  InvalidRequest: -32600,
  UnknownMethod: -32601,
  InvalidParams: -32602,
  InternalError: -32000,
  NoSuchSession: -32001,
  BadToken: -32002,
  SessionFull: -32003,
  LimitExceeded: -32004,
  Busy: -32005,
  EngineRefused: -32006,
  ReadOnlyToken: -32007,
  UnsupportedProtocolVersion: -32008,
  NotInSession: -32009,
  AlreadyInSession: -32010,
  NoSuchStroke: -32011,
  NothingToUndoRedo: -32012,
  UploadMissing: -32013,
  SessionExists: -32014,
  SessionHeldElsewhere: -32015,
  Cancelled: -32016,
  UndoConflict: -32017,
});

const ERROR_NAMES = new Map(Object.entries(RpcErrorCode).map(([name, code]) => [code, name]));

// The RpcErrorCode key of a code ("InvalidParams" for -32602), or "" for a code not in the table.
export function rpcErrorName(code) {
  return ERROR_NAMES.get(code) ?? "";
}

// Where to reconnect after -32015 (session held elsewhere): when the servers share etcd,
// error.data.owner names the server that owns the session (its --server-id, by default
// HOST:PORT). Returns currentUrl with its host and port replaced by the owner's (path and
// query kept), or null when the error names no owner or the name is not a HOST:PORT. Behind a
// load balancer whose servers clients cannot reach, retry through the balancer instead.
export function ownerUrl(error, currentUrl) {
  const owner = error?.code === RpcErrorCode.SessionHeldElsewhere ? error?.data?.owner : undefined;
  if (typeof owner !== "string" || !/^[A-Za-z0-9._-]+:[0-9]{1,5}$/.test(owner)) return null;
  const url = new URL(currentUrl);
  url.host = owner;
  return url.href;
}

// What -32017 (undo conflict, since 1.2) names: `client` (the author of the step in the way, or
// null when not recorded), `revision` (that step's) and `step` (the revision of the caller's
// step that history.undo/redo {scope: "mine"} refused); null for any other error or a malformed
// data.
export function undoConflictOf(error) {
  if (error?.code !== RpcErrorCode.UndoConflict) return null;
  const { client = null, revision, step } = error.data ?? {};
  const count = (v) => Number.isSafeInteger(v) && v >= 1;
  if (!(client === null || count(client)) || !count(revision) || !count(step)) return null;
  return { client, revision, step };
}

// Kinds of incoming message that classifyMessage tells apart.
export const MessageKind = Object.freeze({
  Result: "result", // {jsonrpc, id, result}: the answer to a request
  Error: "error", // {jsonrpc, id, error: {code, message, data?}}; id null when unreadable
  Notification: "notification", // {jsonrpc, method, params?}: no id, nothing to answer
  Invalid: "invalid", // anything else the server must not send (including requests)
});

// Makes requests with increasing integer ids. `firstId` (default 1) is for resuming a
// numbering, e.g. after a reconnect.
export class RequestBuilder {
  #next;

  constructor({ firstId = 1 } = {}) {
    if (!Number.isInteger(firstId) || firstId < 1 || firstId > MAX_REQUEST_ID)
      throw new RangeError(`first request id ${firstId} is outside [1, ${MAX_REQUEST_ID}]`);
    this.#next = firstId;
  }

  // The id the next request gets.
  get nextId() {
    return this.#next;
  }

  // {id, text}: a request that gets a response. `params` is left out when undefined.
  request(method, params) {
    const id = this.#next;
    this.#next = id === MAX_REQUEST_ID ? 1 : id + 1;
    return { id, text: serialize({ jsonrpc: "2.0", id, method, params }) };
  }

  // The text of a client notification: a request without id, carried out without any answer
  // (not even an error), e.g. stroke.dabs at pointer rate.
  notification(method, params) {
    return serialize({ jsonrpc: "2.0", method, params });
  }
}

function serialize(message) {
  if (typeof message.method !== "string") throw new TypeError("a method name must be a string");
  if (message.params !== undefined && !isObject(message.params))
    throw new TypeError("params must be an object (by-name parameters only)");
  return JSON.stringify(message);
}

function isObject(value) {
  return typeof value === "object" && value !== null && !Array.isArray(value);
}

function isId(value) {
  return typeof value === "string" || Number.isSafeInteger(value);
}

function hasOnlyKeys(object, allowed) {
  return Object.keys(object).every((k) => allowed.includes(k));
}

function invalid(reason) {
  return { kind: MessageKind.Invalid, reason };
}

// Sorts one incoming text message into a MessageKind. Never throws. Results:
//   {kind: "result", id, result}
//   {kind: "error", id (null when the request's id could not be read), error: {code, message, data?}}
//   {kind: "notification", method, params (an object; {} when left out)}
//   {kind: "invalid", reason}: not JSON, not one JSON-RPC 2.0 message the server may send.
export function classifyMessage(text) {
  if (typeof text !== "string") return invalid("not a text message");
  let m;
  try {
    m = JSON.parse(text);
  } catch {
    return invalid("not valid JSON");
  }
  if (!isObject(m)) return invalid("not a JSON object");
  if (m.jsonrpc !== "2.0") return invalid('"jsonrpc" must be "2.0"');
  const has = (key) => Object.hasOwn(m, key);
  if (has("method")) {
    if (has("id")) return invalid("a request (the server sends none)");
    if (!hasOnlyKeys(m, ["jsonrpc", "method", "params"])) return invalid("unknown key in a notification");
    if (typeof m.method !== "string") return invalid('"method" must be a string');
    if (has("params") && !isObject(m.params)) return invalid('"params" must be an object');
    return { kind: MessageKind.Notification, method: m.method, params: has("params") ? m.params : {} };
  }
  if (!has("id")) return invalid("neither a response nor a notification");
  if (has("result") === has("error")) return invalid('a response has exactly one of "result" and "error"');
  if (has("result")) {
    if (!hasOnlyKeys(m, ["jsonrpc", "id", "result"])) return invalid("unknown key in a response");
    if (!isId(m.id)) return invalid('"id" must be a string or an integer');
    return { kind: MessageKind.Result, id: m.id, result: m.result };
  }
  if (!hasOnlyKeys(m, ["jsonrpc", "id", "error"])) return invalid("unknown key in an error response");
  if (m.id !== null && !isId(m.id)) return invalid('"id" must be a string, an integer or null');
  const e = m.error;
  if (!isObject(e) || !hasOnlyKeys(e, ["code", "message", "data"])) return invalid('"error" must be {code, message, data?}');
  if (!Number.isSafeInteger(e.code)) return invalid('"error.code" must be an integer');
  if (typeof e.message !== "string") return invalid('"error.message" must be a string');
  return { kind: MessageKind.Error, id: m.id, error: e };
}

// The volume file formats a server's volume.save and volume.load take (protocol 1.3): its
// limits.volume_formats, ["mzv"] or ["mzv", "vdb"] (built with OpenVDB); ["mzv"] before 1.3.
export function volumeFormats(limits) {
  const listed = limits && Array.isArray(limits.volume_formats) ? limits.volume_formats : [];
  return listed.includes("mzv") ? [...listed] : ["mzv", ...listed];
}

// The frame kind that answers volume.save in `format` ("mzv": 8, "vdb": 11).
export function volumeFileKind(format) {
  return format === "vdb" ? FrameKind.VolumeVdb : FrameKind.VolumeFile;
}
