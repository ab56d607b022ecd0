// web-client/net/session-link.js: session ids, share links and the WebSocket URL.
import { test } from "node:test";
import assert from "node:assert/strict";

import { newSessionId, parseSessionLink, sessionLink, socketUrl } from "../../../web-client/net/session-link.js";

test("new ids are 22 base64url characters from the random source", () => {
  const id = newSessionId();
  assert.match(id, /^[A-Za-z0-9_-]{22}$/);
  assert.notEqual(newSessionId(), id);
  assert.equal(newSessionId((b) => b.fill(0)), "A".repeat(22));
  assert.equal(newSessionId((b) => b.fill(255)), "_".repeat(22));
});

test("links carry id and token in the fragment, and read back", () => {
  const link = sessionLink("http://127.0.0.1:8080/?x=1#old", "abcDEF_-0123456789xyzw", "tok_EN-1");
  assert.equal(link, "http://127.0.0.1:8080/?x=1#session=abcDEF_-0123456789xyzw&token=tok_EN-1");
  assert.deepEqual(parseSessionLink(link), { session: "abcDEF_-0123456789xyzw", token: "tok_EN-1", front: null });
  assert.deepEqual(parseSessionLink("#session=s1&token=t1"), { session: "s1", token: "t1", front: null });
});

test("a link may carry the model's front axis; anything but +x -x +z -z is left out", () => {
  const link = sessionLink("http://h/", "s1", "t1", "+x");
  assert.equal(link, "http://h/#session=s1&token=t1&front=%2Bx");
  assert.deepEqual(parseSessionLink(link), { session: "s1", token: "t1", front: "+x" });
  assert.equal(parseSessionLink("#session=s1&token=t1&front=-z").front, "-z");
  for (const bad of ["+y", "x", "%2Bq", "+x+x"]) assert.equal(parseSessionLink(`#session=s1&token=t1&front=${bad}`).front, null, bad);
  assert.equal(sessionLink("http://h/", "s1", "t1", "up"), "http://h/#session=s1&token=t1");
});

test("anything else is not a session link", () => {
  for (const bad of ["", "#", "#session=abc", "#token=abc", "#session=a b&token=c", "#session=ok&token=<x>", `#session=${"a".repeat(65)}&token=t`, null])
    assert.equal(parseSessionLink(bad), null, String(bad));
});

test("the socket URL names the session and never the token", () => {
  assert.equal(socketUrl("http://h:1/page#session=a&token=secret", "abc"), "ws://h:1/ws?session=abc");
  assert.equal(socketUrl("https://h/", "x-_y"), "wss://h/ws?session=x-_y");
});
