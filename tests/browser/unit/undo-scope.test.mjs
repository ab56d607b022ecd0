// web-client/net/undo-scope.js: which undo scope the page uses, the -32017 message, the
// timeline's rows; and plain-errors.js telling an undo conflict.
import { test } from "node:test";
import assert from "node:assert/strict";

import { plainError } from "../../../web-client/net/plain-errors.js";
import { authorName, timelineRows, undoConflictText, undoScope } from "../../../web-client/net/undo-scope.js";

test("undo is the session's while this page is the only editor, mine once another editor is in", () => {
  assert.equal(undoScope([{ client: 3, read_only: false }], 3), "session");
  assert.equal(undoScope([], 3), "session");
  assert.equal(undoScope([{ client: 3, read_only: false }, { client: 5, read_only: true }], 3), "session", "a viewer makes no steps");
  assert.equal(undoScope([{ client: 3, read_only: false }, { client: 5, read_only: false }], 3), "mine");
  assert.equal(undoScope([{ client: 5, read_only: false }, { client: 3, read_only: false }, { client: 9, read_only: true }], 3), "mine");
});

test("a conflict names the client and the revision in the way, and the caller's step", () => {
  const text = undoConflictText({ client: 5, revision: 12, step: 9 }, false, 3);
  assert.equal(
    text,
    "Cannot undo your step at revision 9: client #5 changed the same place at revision 12. Nothing changed; ask them to undo theirs first, or fork from the timeline.",
  );
  assert.match(undoConflictText({ client: 3, revision: 12, step: 9 }, true, 3), /^Cannot redo your step at revision 9: your own later step changed the same place at revision 12\. Nothing changed; undo that step first/);
  assert.match(undoConflictText({ client: null, revision: 4, step: 2 }, false, 3), /a later step changed the same place at revision 4/);
  assert.match(undoConflictText({ client: 5, revision: 12, step: 9 }, false, 3, new Map([[5, "Bea"]])), /: Bea \(client #5\) changed the same place at revision 12\./, "by name while they are in");
});

test("plain-errors tells -32017 with the conflict, and without one still says nothing changed", () => {
  const e = { name: "RpcError", method: "history.undo", code: -32017, codeName: "UndoConflict", message: "undo conflict", data: { client: 5, revision: 12, step: 9 }, conflict: { client: 5, revision: 12, step: 9 }, self: 3 };
  const { text, detail } = plainError(e);
  assert.match(text, /client #5 changed the same place at revision 12/);
  assert.equal(detail, "history.undo: undo conflict [-32017 UndoConflict]");
  assert.match(plainError({ ...e, conflict: null }).text, /nothing changed/);
});

test("timeline rows: author, tool as read, time, undone", () => {
  const steps = [
    { revision: 4, first_revision: 2, client: 3, tool: "add_blob", time_ms: 0, region: null, undone: false },
    { revision: 7, first_revision: 5, client: 5, tool: "csg_subtract", time_ms: 1000, region: null, undone: false },
    { revision: 8, first_revision: 8, client: null, tool: "new_tool", time_ms: 2000, region: null, undone: true },
  ];
  const rows = timelineRows(steps, 3, (ms) => `t${ms}`);
  assert.deepEqual(rows, [
    { revision: 4, author: "you", tool: "add blob", time: "t0", undone: false, mine: true },
    { revision: 7, author: "#5", tool: "CSG subtract", time: "t1000", undone: false, mine: false },
    { revision: 8, author: "someone", tool: "new tool", time: "t2000", undone: true, mine: false },
  ]);
  assert.equal(authorName(undefined, 3), "someone");
  // Since protocol 1.2 a step carries its author's display name: the timeline says it.
  const named = timelineRows([{ ...steps[1], name: "Bea" }, { ...steps[0], name: "Ada" }, { ...steps[1], name: "" }], 3, (ms) => `t${ms}`);
  assert.deepEqual(named.map((r) => r.author), ["Bea", "you", "#5"]);
  assert.equal(authorName(5, 3, "Bea"), "Bea");
  // A step without a name of its own takes its author's from the session's clients while they are in.
  const fromClients = timelineRows(steps, 3, (ms) => `t${ms}`, new Map([[5, "Bea"], [3, "Ada"]]));
  assert.deepEqual(fromClients.map((r) => r.author), ["you", "Bea", "someone"]);
  assert.equal(timelineRows([{ ...steps[1], name: "Old" }], 3, (ms) => `t${ms}`, new Map([[5, "Bea"]]))[0].author, "Old", "the step's own name first");
  assert.match(timelineRows(steps.slice(0, 1), 3)[0].time, /^\d\d:\d\d:\d\d$/);
});
