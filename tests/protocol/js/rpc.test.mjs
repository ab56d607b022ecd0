// protocol/js/rpc.js against the example messages of the golden vectors and the tables of
// protocol/PROTOCOL.md.
import { test } from "node:test";
import assert from "node:assert/strict";

import {
  BINARY_METHODS,
  MAX_REQUEST_ID,
  METHODS,
  MessageKind,
  PROTOCOL_VERSION,
  RequestBuilder,
  RpcErrorCode,
  classifyMessage,
  ownerUrl,
  rpcErrorName,
  undoConflictOf,
  volumeFileKind,
  volumeFormats,
} from "../../../protocol/js/rpc.js";
import { FrameKind } from "../../../protocol/js/frames.js";
import { protocolMarkdown, vectors } from "./vectors.mjs";

test("the method lists and the protocol version are those of the vectors", () => {
  assert.deepEqual([...METHODS], vectors.methods);
  assert.deepEqual([...BINARY_METHODS], vectors.binary_methods);
  assert.deepEqual({ ...PROTOCOL_VERSION }, vectors.protocol);
});

test("RpcErrorCode holds exactly the codes of PROTOCOL.md's error table", () => {
  const section = protocolMarkdown.slice(protocolMarkdown.indexOf("\n## Errors"), protocolMarkdown.indexOf("\n## Closing"));
  const documented = [...section.matchAll(/^\| (-32\d{3}) \|/gm)].map((m) => Number(m[1]));
  assert.ok(documented.length >= 18);
  assert.deepEqual(Object.values(RpcErrorCode).sort(), documented.sort());
  for (const code of documented) assert.notEqual(rpcErrorName(code), "");
  assert.equal(rpcErrorName(-32602), "InvalidParams");
  assert.equal(rpcErrorName(-32014), "SessionExists");
  assert.equal(rpcErrorName(-32015), "SessionHeldElsewhere");
  assert.equal(rpcErrorName(-32016), "Cancelled");
  assert.equal(rpcErrorName(-32017), "UndoConflict");
  assert.equal(rpcErrorName(-32018), "");
});

test("responses with a result are classified as results", () => {
  for (const r of vectors.responses) {
    const c = classifyMessage(r.text);
    assert.equal(c.kind, MessageKind.Result, `${r.name}: ${c.reason}`);
    const m = JSON.parse(r.text);
    assert.equal(c.id, m.id, r.name);
    assert.deepEqual(c.result, m.result, r.name);
  }
});

test("error responses are classified as errors with their code", () => {
  for (const e of vectors.errors) {
    const c = classifyMessage(e.text);
    assert.equal(c.kind, MessageKind.Error, `${e.name}: ${c.reason}`);
    assert.equal(c.error.code, e.code, e.name);
    assert.notEqual(rpcErrorName(c.error.code), "", e.name);
    assert.equal(c.id, JSON.parse(e.text).id, e.name);
  }
});

test("notifications are classified as notifications of their method", () => {
  for (const n of vectors.notifications) {
    const c = classifyMessage(n.text);
    assert.equal(c.kind, MessageKind.Notification, `${n.name}: ${c.reason}`);
    assert.equal(c.method, n.method, n.name);
    assert.deepEqual(c.params, JSON.parse(n.text).params, n.name);
  }
});

test("requests, valid or not, are nothing a client may receive", () => {
  // A request without id (a client notification) has the very shape of a server notification.
  for (const r of vectors.requests) {
    const c = classifyMessage(r.text);
    if ("id" in JSON.parse(r.text)) assert.equal(c.kind, MessageKind.Invalid, r.name);
    else assert.deepEqual([c.kind, c.method], [MessageKind.Notification, r.method], r.name);
  }
  for (const r of vectors.invalid_requests) {
    const c = classifyMessage(r.text);
    assert.equal(c.kind, MessageKind.Invalid, r.name);
    assert.ok(c.reason.length > 0, r.name);
  }
});

test("malformed messages are invalid and never throw", () => {
  const texts = [
    "",
    "null",
    "[]",
    '{"jsonrpc":"2.0","id":1}',
    '{"jsonrpc":"1.0","id":1,"result":{}}',
    '{"jsonrpc":"2.0","id":1,"result":{},"error":{"code":-32000,"message":"x"}}',
    '{"jsonrpc":"2.0","id":1.5,"result":{}}',
    '{"jsonrpc":"2.0","id":null,"result":{}}',
    '{"jsonrpc":"2.0","id":1,"result":{},"extra":1}',
    '{"jsonrpc":"2.0","id":1,"error":{"code":"x","message":"m"}}',
    '{"jsonrpc":"2.0","id":1,"error":{"code":-32000}}',
    '{"jsonrpc":"2.0","id":1,"error":{"code":-32000,"message":"m","extra":1}}',
    '{"jsonrpc":"2.0","id":1,"error":"boom"}',
    '{"jsonrpc":"2.0","method":"session.changed","params":[1]}',
    '{"jsonrpc":"2.0","method":7}',
    '{"jsonrpc":"2.0","method":"session.changed","params":{},"extra":1}',
  ];
  for (const text of texts) assert.equal(classifyMessage(text).kind, MessageKind.Invalid, text);
  for (const value of [undefined, null, 42, new Uint8Array(4)])
    assert.equal(classifyMessage(value).kind, MessageKind.Invalid);
  const unknown = classifyMessage('{"jsonrpc":"2.0","method":"session.future"}');
  assert.deepEqual(unknown, { kind: MessageKind.Notification, method: "session.future", params: {} });
  const unreadable = classifyMessage('{"jsonrpc":"2.0","id":null,"error":{"code":-32600,"message":"m"}}');
  assert.equal(unreadable.kind, MessageKind.Error);
  assert.equal(unreadable.id, null);
});

test("requests get increasing integer ids that wrap from 2^32-1 to 1", () => {
  const builder = new RequestBuilder();
  assert.equal(builder.nextId, 1);
  const ids = [];
  for (const r of vectors.requests) {
    const m = JSON.parse(r.text);
    const { id, text } = builder.request(m.method, m.params);
    ids.push(id);
    const sent = JSON.parse(text);
    assert.deepEqual(Object.keys(sent).sort(), m.params === undefined ? ["id", "jsonrpc", "method"] : ["id", "jsonrpc", "method", "params"]);
    assert.equal(sent.jsonrpc, "2.0");
    assert.equal(sent.id, id);
    assert.equal(sent.method, m.method);
    assert.deepEqual(sent.params, m.params);
  }
  assert.deepEqual(ids, vectors.requests.map((_, i) => i + 1));
  const late = new RequestBuilder({ firstId: MAX_REQUEST_ID - 1 });
  assert.deepEqual([late.request("history.undo").id, late.request("history.undo").id, late.request("history.undo").id], [
    MAX_REQUEST_ID - 1,
    MAX_REQUEST_ID,
    1,
  ]);
  for (const firstId of [0, MAX_REQUEST_ID + 1, 1.5]) assert.throws(() => new RequestBuilder({ firstId }), RangeError);
  assert.throws(() => builder.request("session.stats", [1]), TypeError);
  assert.throws(() => builder.request(5, {}), TypeError);
});

test("client notifications carry no id", () => {
  const builder = new RequestBuilder();
  const dabs = { stroke: 1, dabs: [{ center: [1, 2, 3] }] };
  const sent = JSON.parse(builder.notification("stroke.dabs", dabs));
  assert.deepEqual(sent, { jsonrpc: "2.0", method: "stroke.dabs", params: dabs });
  assert.equal(builder.nextId, 1);
});

test("ownerUrl: -32015's data.owner as the URL to reconnect to, path and session kept", () => {
  const held = { code: -32015, message: "held elsewhere", data: { owner: "server-b:8080" } };
  assert.equal(ownerUrl(held, "ws://lb.example:80/ws?session=abc"), "ws://server-b:8080/ws?session=abc");
  assert.equal(ownerUrl(held, "wss://lb.example/ws?session=abc"), "wss://server-b:8080/ws?session=abc");
  assert.equal(ownerUrl({ code: -32015, message: "m" }, "ws://a:1/ws"), null);
  assert.equal(ownerUrl({ code: -32015, message: "m", data: { owner: "host-1234" } }, "ws://a:1/ws"), null);
  assert.equal(ownerUrl({ code: -32015, message: "m", data: { owner: "evil.example:80/x" } }, "ws://a:1/ws"), null);
  assert.equal(ownerUrl({ code: -32001, message: "m", data: { owner: "b:1" } }, "ws://a:1/ws"), null);
});

test("undoConflictOf reads -32017's data and nothing else", () => {
  const vector = vectors.errors.find((e) => e.code === RpcErrorCode.UndoConflict);
  const c = classifyMessage(vector.text);
  assert.deepEqual(undoConflictOf(c.error), { client: 2, revision: 5, step: 3 });
  const conflict = (data) => undoConflictOf({ code: -32017, message: "m", data });
  assert.deepEqual(conflict({ client: null, revision: 5, step: 3 }), { client: null, revision: 5, step: 3 });
  assert.equal(conflict({ client: 2, revision: "5", step: 3 }), null);
  assert.equal(conflict({ client: 0, revision: 5, step: 3 }), null);
  assert.equal(conflict(undefined), null);
  assert.equal(undoConflictOf({ code: -32012, message: "m", data: { client: 2, revision: 5, step: 3 } }), null);
  assert.equal(undoConflictOf(undefined), null);
});

test("volumeFormats reads limits.volume_formats of the vectors' join result, mzv before 1.3", () => {
  const joined = vectors.responses.find((v) => v.method === "session.join" && v.text.includes("volume_formats"));
  assert.deepEqual(volumeFormats(JSON.parse(joined.text).result.limits), ["mzv", "vdb"]);
  assert.deepEqual(volumeFormats({ max_text_bytes: 1048576 }), ["mzv"]);
  assert.deepEqual(volumeFormats(undefined), ["mzv"]);
  assert.deepEqual(volumeFormats({ volume_formats: ["mzv"] }), ["mzv"]);
  assert.equal(volumeFileKind("vdb"), FrameKind.VolumeVdb);
  assert.equal(volumeFileKind("mzv"), FrameKind.VolumeFile);
  const vdbFrame = vectors.binary.find((v) => v.header.kind_name === "volume_vdb");
  assert.equal(vdbFrame.header.kind, volumeFileKind("vdb"));
});
