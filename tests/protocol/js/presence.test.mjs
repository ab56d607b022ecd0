// protocol/js/presence.js against the presence vectors and PROTOCOL.md's rules.
import { test } from "node:test";
import assert from "node:assert/strict";

import { PresenceBoard, presenceParams } from "../../../protocol/js/presence.js";
import { RequestBuilder, classifyMessage } from "../../../protocol/js/rpc.js";
import { vectors } from "./vectors.mjs";

const brush = { tool: "add_blob", radius: 6, point: [12.5, 20, 16], normal: [0, 1, 0], active: true };
const camera = { eye: [16, 16, 80], target: [16, 16, 16] };

test("presenceParams builds the request of the vectors", () => {
  const request = vectors.requests.find((r) => r.method === "presence");
  const text = new RequestBuilder({ firstId: 30 }).request("presence", presenceParams({ brush, camera })).text;
  assert.deepEqual(JSON.parse(text), JSON.parse(request.text));
  assert.deepEqual(presenceParams({ camera }), { camera });
  assert.deepEqual(presenceParams(), {});
});

test("presenceParams refuses what the server would", () => {
  const bad = [
    { brush: { ...brush, tool: "hammer" } },
    { brush: { ...brush, radius: 2000 } },
    { brush: { ...brush, point: [1, 2] } },
    { brush: { ...brush, point: [Number.NaN, 0, 0] } },
    { brush: { ...brush, normal: [0, 0, 0] } },
    { brush: { ...brush, active: 1 } },
    { brush: { ...brush, extra: 1 } },
    { brush: { ...brush, color: [255, 0] } },
    { brush: { ...brush, color: [256, 0, 0] } },
    { brush: { ...brush, color: [1.5, 0, 0] } },
    { brush: { ...brush, color: "#ff0000" } },
    { camera: { eye: [1, 2, 3], target: [1, 2, 3] } },
    { camera: { ...camera, fov: 200 } },
    { camera: { ...camera, width: 10 } },
  ];
  for (const params of bad) assert.throws(() => presenceParams(params), JSON.stringify(params));
});

test("a brush may carry the paint colour, [r, g, b] in 0..255", () => {
  const painting = { ...brush, tool: "add_blob", color: [200, 20, 10] };
  assert.deepEqual(presenceParams({ brush: painting }).brush.color, [200, 20, 10]);
  assert.equal("color" in presenceParams({ brush }).brush, false);
  assert.deepEqual(presenceParams({ brush: { ...brush, color: [0, 255, 0] } }).brush.color, [0, 255, 0]);
});

test("PresenceBoard keeps the others' newest presence and forgets those gone", () => {
  const board = new PresenceBoard();
  const seen = [];
  board.addEventListener("presence", (e) => seen.push(e.presence.client));
  board.addEventListener("gone", (e) => seen.push(-e.client));
  for (const n of vectors.notifications.filter((v) => v.method === "presence"))
    assert.equal(board.handle(classifyMessage(n.text)), true, n.name);
  const forwarded = JSON.parse(vectors.notifications.find((v) => v.name === "client 1's presence forwarded").text);
  assert.deepEqual(board.others.get(1), forwarded.params);
  assert.deepEqual(seen, [1, -2]);
  // A late presence of a client that is gone is ignored; malformed ones are too.
  assert.equal(board.handle({ method: "presence", params: { client: 2, name: "B", color: "#3cb44b" } }), false);
  assert.equal(board.handle({ method: "presence", params: { client: "x", name: "B", color: "#3cb44b" } }), false);
  assert.equal(board.handle({ method: "session.changed", params: {} }), false);
  assert.equal(board.others.size, 1);
  board.clear();
  assert.equal(board.others.size, 0);
});
