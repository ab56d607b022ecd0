// web-client/net/plain-errors.js: errors told in plain language, the protocol's words as detail.
import { test } from "node:test";
import assert from "node:assert/strict";

import { plainError } from "../../../web-client/net/plain-errors.js";

const rpc = (method, code, codeName, message, data) => ({ name: "RpcError", method, code, codeName, message, data });

test("a refused upload says the file is not a volume, with the server's words as detail", () => {
  const { text, detail } = plainError(rpc("volume.load", -32006, "EngineRefused", "not a Marzipan volume file (bad magic)"));
  assert.equal(text, "This file is not a Marzipan volume (.mzv) that fits this session.");
  assert.equal(detail, "volume.load: not a Marzipan volume file (bad magic) [-32006 EngineRefused]");
});

// The format is the request's own (RpcError.params, net/connection.js): the text is made as the
// request fails, before the caller could add anything to the error.
test("a refused .vdb upload names OpenVDB, not .mzv", () => {
  const vdb = { bytes: 200, format: "vdb" };
  const refused = { ...rpc("volume.load", -32006, "EngineRefused", "not an OpenVDB level set: no grid of class level set"), params: vdb };
  assert.equal(plainError(refused).text, "This file is not an OpenVDB level set (.vdb) that fits this session.");
  const invalid = { ...rpc("volume.load", -32602, "InvalidParams", "bytes: too large", { field: "bytes" }), params: vdb };
  assert.equal(plainError(invalid).text, "This file is not an OpenVDB level set (.vdb) that fits this session.");
  assert.equal(plainError({ ...refused, params: { bytes: 200 } }).text, "This file is not a Marzipan volume (.mzv) that fits this session.");
});

test("limits keep the server's sentence; undo and redo say which", () => {
  assert.equal(plainError(rpc("tool.apply", -32004, "LimitExceeded", "radius above max_radius 64.")).text,
    "That goes beyond what this server allows: radius above max_radius 64.");
  assert.equal(plainError(rpc("history.undo", -32012, "NothingToUndoRedo", "nothing to undo")).text, "There is nothing to undo.");
  assert.equal(plainError(rpc("history.redo", -32012, "NothingToUndoRedo", "nothing to redo")).text, "There is nothing to redo.");
  assert.equal(plainError(rpc("tool.apply", -32016, "Cancelled", "the operation was cancelled")).text, "The operation was cancelled; the session is unchanged.");
});

test("a field named by the server stays in the detail; unknown codes still read as a sentence", () => {
  const e = plainError(rpc("tool.apply", -32602, "InvalidParams", "must be finite", { field: "radius" }));
  assert.equal(e.text, "The server refused a value this page sent.");
  assert.match(e.detail, /\(field "radius"\) \[-32602 InvalidParams\]$/);
  assert.equal(plainError(rpc("x", -31999, "-31999", "odd")).text, "The server refused it: odd.");
});

test("errors that are not the server's keep their message", () => {
  assert.deepEqual(plainError(new Error("splat buffer refused")), { text: "splat buffer refused", detail: "" });
  assert.equal(plainError({ name: "ConnectionLost", message: "closed before tool.apply" }).text, "The connection dropped before the server answered.");
});
