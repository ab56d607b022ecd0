// protocol/js/tools.js, the tool registry as generated JavaScript, against
// protocol/registry/tools.json itself; and presence.js, which takes its tool names from it.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";

import { GROUPS, OPERATIONS, PARAMETERS, TOOLS, TOOL_NAMES } from "../../../protocol/js/tools.js";
import { PRESENCE_TOOLS, presenceParams } from "../../../protocol/js/presence.js";

const registry = JSON.parse(readFileSync(new URL("../../../protocol/registry/tools.json", import.meta.url), "utf8"));

test("the module holds the registry: its groups, tools, operations and parameters", () => {
  assert.deepEqual(GROUPS.map((g) => ({ ...g })), registry.groups);
  assert.deepEqual(TOOL_NAMES, registry.tools.map((t) => t.name));
  for (const [id, p] of Object.entries(registry.parameters)) {
    const { id: ownId, key, ...rest } = PARAMETERS[id];
    assert.deepEqual([ownId, key], [id, p.key ?? id]);
    assert.deepEqual(rest, Object.fromEntries(Object.entries(p).filter(([k]) => k !== "key")), id);
  }
  for (const [list, entries] of [[TOOLS, registry.tools], [OPERATIONS, registry.operations]])
    entries.forEach((r, i) => {
      const t = list[i];
      assert.equal(t.name, r.name);
      assert.deepEqual(t.params.map((p) => p.id), r.params);
      for (const p of t.params) assert.equal(p, PARAMETERS[p.id], "a tool's parameters are the shared objects");
      assert.deepEqual(t.browser, r.browser);
      for (const k of ["label", "kind", "description"]) assert.equal(t[k], r[k], `${r.name}.${k}`);
    });
  for (const t of TOOLS) {
    const r = registry.tools.find((x) => x.name === t.name);
    assert.deepEqual([t.group, t.strokes, t.dabs, t.inverse], [r.group, r.strokes, r.dabs ?? "swept", r.inverse ?? null]);
  }
});

test("everything is frozen", () => {
  assert.ok(Object.isFrozen(TOOLS) && Object.isFrozen(TOOLS[0]) && Object.isFrozen(TOOLS[0].browser.color));
  assert.ok(Object.isFrozen(PARAMETERS.radius) && Object.isFrozen(PARAMETERS.radius.in));
  assert.throws(() => TOOLS.push({}), TypeError);
});

test("presence takes every tool of the registry, and nothing else", () => {
  assert.deepEqual(PRESENCE_TOOLS, registry.tools.map((t) => t.name));
  const brush = { radius: registry.parameters.radius.maximum, point: [1, 2, 3], normal: [0, 1, 0], active: false };
  for (const tool of PRESENCE_TOOLS) assert.equal(presenceParams({ brush: { ...brush, tool } }).brush.tool, tool);
  assert.throws(() => presenceParams({ brush: { ...brush, tool: "morph" } }), RangeError);
  assert.throws(() => presenceParams({ brush: { ...brush, tool: "add_blob", radius: registry.parameters.radius.maximum + 1 } }), RangeError);
});
