// What a page draws and lists of the others (web-client/math/presence-rings.js,
// web-client/ui/people.js), following a camera (web-client/ui/follow.js) and taking another
// client's camera (OrbitCamera.setFromProtocol).
import { test } from "node:test";
import assert from "node:assert/strict";

import { EDIT_MARK_MS, EditMarks, boxEdges, hexColor, presenceRings, project } from "../../../web-client/math/presence-rings.js";
import { OrbitCamera, ORTHOGRAPHIC_FOV_DEGREES } from "../../../web-client/math/orbit-camera.js";
import { Follow } from "../../../web-client/ui/follow.js";
import { PeopleList, followNote, peopleRows } from "../../../web-client/ui/people.js";
import { TOOLS, toolName } from "../../../web-client/ui/tools.js";

const near = (a, b, eps = 1e-9) => a.every((v, k) => Math.abs(v - b[k]) <= eps * Math.max(1, Math.abs(b[k])));

function cameraAt({ yaw = 0.3, pitch = 0.2, distance = 200, target = [64, 64, 64] } = {}) {
  const c = new OrbitCamera([128, 128, 128]);
  c.setState({ target, distance, yaw, pitch });
  return c;
}

test("hex colours", () => {
  assert.deepEqual(hexColor("#ff0080"), [1, 0, 128 / 255]);
  assert.equal(hexColor("ff0080"), null);
  assert.equal(hexColor("#ff008"), null);
  assert.equal(hexColor(null), null);
});

// The view-projection matrix is Float32 (math/mat4.js): screen positions hold to about 1e-5 px.
test("a ring at the target: its label is centred above it, one radius up on screen; its line 2 px wide at its depth", () => {
  const [w, h] = [800, 600];
  const c = cameraAt().update(w, h);
  const brush = { tool: "add_blob", radius: 10, point: [...c.target], normal: c.backward, active: false };
  const { rings, labels } = presenceRings([{ client: 2, name: "Ada", color: "#e6194b", brush, seenAt: 0 }], c, w, h, 100, 6000);
  assert.equal(rings.length, 1);
  const tan = Math.tan(c.fovY / 2);
  assert.ok(Math.abs(rings[0].width - (2 * 2 * tan * 200) / h) < 1e-9, "2 px at the ring's depth");
  assert.equal(rings[0].alpha, 0.7);
  assert.equal(rings[0].primary, false);
  assert.deepEqual(rings[0].color, hexColor("#e6194b"));
  const [label] = labels;
  assert.equal(label.visible, true);
  assert.equal(label.tool, "add_blob", "the label carries the tool, whose icon it shows");
  assert.ok(Math.abs(label.x - w / 2) < 1e-3, `x ${label.x}`);
  // one radius at the target's depth is 10 / (200 tan(fov/2)) of the half height; the label
  // sits 4 px above that
  assert.ok(Math.abs(label.y - (h / 2 - (10 / (200 * tan)) * (h / 2) - 4)) < 1e-3, `y ${label.y}`);
});

test("a painting client's ring is drawn in its paint colour, a malformed one in the client's", () => {
  const [w, h] = [800, 600];
  const c = cameraAt().update(w, h);
  const brush = { tool: "paint", radius: 10, point: [...c.target], normal: c.backward, active: true, color: [255, 0, 51] };
  const ring = (b) => presenceRings([{ client: 2, name: "Ada", color: "#e6194b", brush: b, seenAt: 0 }], c, w, h, 100, 6000).rings[0];
  assert.deepEqual(ring(brush).color, [1, 0, 0.2]);
  assert.deepEqual(ring({ ...brush, color: [256, 0, 0] }).color, hexColor("#e6194b"));
  assert.deepEqual(ring({ ...brush, color: "#00ff00" }).color, hexColor("#e6194b"));
  assert.deepEqual(ring({ ...brush, color: undefined }).color, hexColor("#e6194b"));
});

test("a sculpting client's ring is thicker, brighter and dotted; one facing away is faint; a stale one is gone", () => {
  const [w, h] = [640, 480];
  const c = cameraAt().update(w, h);
  const point = [...c.target];
  const mk = (client, brush, seenAt = 0) => ({ client, name: `n${client}`, color: "#3cb44b", brush: { tool: "smooth", radius: 5, point, ...brush }, seenAt });
  const { rings } = presenceRings(
    [mk(1, { normal: c.backward, active: true }), mk(2, { normal: c.backward.map((v) => -v), active: false }), mk(3, { normal: c.backward, active: false }, -7000), { client: 4, name: "x", color: "#123456", seenAt: 0 }],
    c,
    w,
    h,
    0,
    6000,
  );
  assert.deepEqual(rings.map((r) => r.client), [1, 2], "3 is stale, 4 has no brush");
  assert.equal(rings[0].primary, true);
  assert.equal(rings[0].alpha, 0.95);
  assert.ok(Math.abs(rings[0].width / rings[1].width - 1.5) < 1e-12);
  assert.ok(Math.abs(rings[1].alpha - 0.7 * 0.4) < 1e-12, "a ring seen through the model is fainter");
});

test("projection: the target in the middle, a point behind the eye not visible", () => {
  const c = cameraAt().update(400, 300);
  const mid = project(c.viewProjection, c.target, 400, 300);
  assert.ok(Math.abs(mid.x - 200) < 1e-3 && Math.abs(mid.y - 150) < 1e-3 && mid.visible);
  const behind = c.eye.map((v, k) => v + 10 * c.backward[k]);
  assert.equal(project(c.viewProjection, behind, 400, 300).visible, false);
});

test("an edit's mark: the box of the changed voxels in the author's colour, fading out, the newest per author", () => {
  const edges = boxEdges({ lo: [0, 0, 0], hi: [2, 3, 4] });
  assert.equal(edges.length, 12);
  const lengths = edges.map(([a, b]) => Math.hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2])).sort();
  assert.deepEqual(lengths, [1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3], "voxel centres 0..1, 0..2, 0..3");
  const marks = new EditMarks();
  assert.equal(marks.add(2, { lo: [0, 0, 0], hi: [8, 8, 8] }, "#e6194b", 1000), true);
  assert.equal(marks.add(3, { lo: [8, 8, 8], hi: [16, 16, 16] }, "not a colour", 1000), false);
  assert.equal(marks.add(3, null, "#3cb44b", 1000), false);
  let shown = marks.marks(1000);
  assert.equal(shown.length, 1);
  assert.equal(shown[0].alpha, 0.9);
  assert.deepEqual(shown[0].color, hexColor("#e6194b"));
  assert.ok(Math.abs(marks.marks(1000 + EDIT_MARK_MS / 2)[0].alpha - 0.45) < 1e-12, "half way: half as strong");
  marks.add(2, { lo: [16, 16, 16], hi: [24, 24, 24] }, "#e6194b", 1200);
  shown = marks.marks(1200);
  assert.equal(shown.length, 1, "a newer edit of the same author replaces its mark");
  assert.deepEqual(shown[0].segments[0][0], [16, 16, 16]);
  assert.deepEqual(marks.marks(1200 + EDIT_MARK_MS), [], "gone after EDIT_MARK_MS");
  assert.equal(marks.size, 0);
});

test("following: a click follows (taking the newest camera), the leader's cameras only, until you move, they leave, or a second click", () => {
  const changes = [];
  const f = new Follow((s) => changes.push(s));
  const cam = { eye: [1, 2, 3], target: [0, 0, 0] };
  assert.equal(f.toggle(5, (id) => (id === 5 ? cam : null)), cam);
  assert.deepEqual(changes.at(-1), { leader: 5, following: true, reason: null });
  assert.equal(f.cameraFrom({ client: 5, camera: cam }), cam);
  assert.equal(f.cameraFrom({ client: 6, camera: cam }), null, "not the leader");
  assert.equal(f.cameraFrom({ client: 5 }), null, "no camera");
  assert.equal(f.userMoved(), true);
  assert.deepEqual(changes.at(-1), { leader: null, following: false, reason: "you moved the camera" });
  assert.equal(f.cameraFrom({ client: 5, camera: cam }), null, "following stopped");
  assert.equal(f.userMoved(), false, "moving while not following changes nothing");
  f.toggle(6);
  f.gone(5);
  assert.equal(f.leader, 6, "someone else leaving does not stop it");
  f.gone(6);
  assert.deepEqual(changes.at(-1), { leader: null, following: false, reason: "they left" });
  f.forgetReason();
  assert.equal(f.reason, null);
  f.toggle(7);
  assert.equal(f.toggle(7), null);
  assert.equal(f.following, false, "a second click on the leader stops");
  assert.equal(followNote("Ada", null), "Following Ada: your view copies theirs. Orbit or zoom to stop.");
  assert.equal(followNote(null, "you moved the camera"), "Stopped following: you moved the camera.");
  assert.equal(followNote(null, "stopped"), "");
});

test("the people list: this page first, names and colours, the tool each shows, view only, who is followed", () => {
  const clients = [
    { client: 1, read_only: false, name: "Ada", color: "#e6194b" },
    { client: 4, read_only: true, name: "Cy", color: "#4363d8" },
    { client: 2, read_only: false, name: "Bea", color: "#3cb44b" },
    { client: 5, read_only: false, name: "Dee", color: "#ffe119" },
  ];
  const presence = new Map([[1, { client: 1, brush: { tool: "csg_subtract", active: false } }], [2, { client: 2, brush: { tool: "smooth", active: true } }]]);
  const tools = new Map([[5, "remove_blob"]]);
  const rows = peopleRows(clients, 2, presence, tools, 1);
  assert.deepEqual(
    rows.map((r) => [r.client, r.name, r.you, r.doing, r.followed, r.active]),
    [
      [2, "Bea", true, "smooth · sculpting", false, true],
      [1, "Ada", false, "csg subtract", true, false],
      [4, "Cy", false, "view only", false, false],
      [5, "Dee", false, "remove blob", false, false],
    ],
  );
  assert.equal(rows[1].color, "#e6194b");
  assert.deepEqual(peopleRows([{ client: 9, read_only: false }], 1, new Map(), new Map(), null)[0].name, "#9", "a client without a name");
});

test("every tool of the registry shows in the people list by its name, warps and surface tools alike", () => {
  for (const t of TOOLS) {
    const presence = new Map([[3, { client: 3, brush: { tool: t.id, active: true } }]]);
    const [row] = peopleRows([{ client: 3, read_only: false, name: "Ada", color: "#e6194b" }], 1, presence, new Map(), null);
    assert.equal(row.doing, `${toolName(t.id).toLowerCase()} · sculpting`, t.id);
    assert.ok(!row.doing.includes("_"), `${t.id} is named in words: ${row.doing}`);
  }
});

test("taking another client's camera gives exactly its eye, target and up, at the poles and in the telephoto view too", () => {
  const states = [
    { yaw: 0.3, pitch: 0.2, distance: 200, target: [64, 64, 64] },
    { yaw: -2.9, pitch: -1.1, distance: 90, target: [10, 100, 30] },
    { yaw: 0.7, pitch: Math.PI / 2, distance: 150, target: [64, 64, 64] },
    { yaw: -1.2, pitch: -Math.PI / 2, distance: 150, target: [64, 20, 64] },
  ];
  for (const s of states) {
    const leader = cameraAt(s);
    const want = leader.toProtocol();
    const follower = cameraAt({ yaw: 2, pitch: -0.5, distance: 300 });
    follower.setFromProtocol(want);
    const got = follower.toProtocol();
    assert.ok(near(got.eye, want.eye, 1e-9) && near(got.target, want.target) && near(got.up, want.up, 1e-9), `${JSON.stringify(s)}: ${JSON.stringify(got)} vs ${JSON.stringify(want)}`);
    assert.equal(got.fov, want.fov);
  }
  const leader = cameraAt();
  leader.setOrthographic(true);
  const follower = cameraAt();
  follower.setFromProtocol(leader.toProtocol());
  assert.equal(follower.orthographic, true);
  assert.equal(follower.fovDegrees, ORTHOGRAPHIC_FOV_DEGREES);
  assert.ok(near(follower.eye, leader.eye, 1e-9), "the telephoto camera stands as far back as the leader's");
  follower.setFromProtocol({ eye: [64, 64, 300], target: [64, 64, 64] });
  assert.equal(follower.orthographic, false, "a camera without fov is the default 40°");
  assert.ok(near(follower.eye, [64, 64, 300]));
});

// Just enough of a document for PeopleList: elements keep their children and count rebuilds.
class FakeElement {
  constructor(tag) {
    Object.assign(this, { tag, children: [], dataset: {}, style: {}, attributes: {}, listeners: {}, rebuilt: 0, hidden: false });
    this.classList = { add: () => {} };
  }
  append(...c) {
    this.children.push(...c);
  }
  replaceChildren(...c) {
    this.children = c;
    this.rebuilt += 1;
  }
  setAttribute(k, v) {
    this.attributes[k] = v;
  }
  addEventListener(type, f) {
    this.listeners[type] = f;
  }
}

test("the people list is rebuilt only when its rows change, so a Follow button stays under a click", () => {
  const byId = { people: new FakeElement("section"), "people-list": new FakeElement("ul"), "follow-note": new FakeElement("p") };
  const doc = { getElementById: (id) => byId[id], createElement: (tag) => new FakeElement(tag) };
  const followed = [];
  const list = new PeopleList(doc, (client) => followed.push(client));
  const clients = [
    { client: 1, name: "Ada", color: "#ff0000" },
    { client: 2, name: "Bea", color: "#00ff00" },
  ];
  const board = (x) => new Map([[1, { brush: { tool: "add_blob", active: false, center: [x, 0, 0] } }]]);
  list.show(peopleRows(clients, 2, board(1), new Map(), null), "");
  const button = byId["people-list"].children.find((li) => li.dataset.client === "1").children[0];
  assert.equal(button.className, "follow");
  // Ada's pointer moves: her presence changes, her row does not.
  for (let x = 2; x < 40; ++x) list.show(peopleRows(clients, 2, board(x), new Map(), null), "");
  assert.equal(byId["people-list"].rebuilt, 1);
  assert.equal(byId["people-list"].children.find((li) => li.dataset.client === "1").children[0], button, "the same button");
  button.listeners.click();
  assert.deepEqual(followed, [1]);
  // Her stroke begins: the row says so.
  list.show(peopleRows(clients, 2, new Map([[1, { brush: { tool: "add_blob", active: true } }]]), new Map(), null), "");
  assert.equal(byId["people-list"].rebuilt, 2);
  assert.equal(byId["people-list"].children.find((li) => li.dataset.client === "1").dataset.doing, "add blob · sculpting");
});
