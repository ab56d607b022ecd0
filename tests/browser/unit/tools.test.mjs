// web-client/ui/tools.js (and the keys of ui/shortcuts.js, the heights of net/stroke-sender.js):
// the palette is the tool registry's, read here from protocol/registry/tools.json itself.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";

import { GLOBAL_OPS, GROUPS, TOOLS, toolById, toolName, toolWithModifier } from "../../../web-client/ui/tools.js";
import { KEY_HELP, PAGE_KEYS } from "../../../web-client/ui/shortcuts.js";
import { strokeBeginParams } from "../../../web-client/net/stroke-sender.js";

const registry = JSON.parse(readFileSync(new URL("../../../protocol/registry/tools.json", import.meta.url), "utf8"));
const entry = (name) => registry.tools.find((t) => t.name === name);

test("the palette holds every tool of the registry once, in its order, under its group", () => {
  assert.deepEqual(TOOLS.map((t) => t.id), registry.tools.map((t) => t.name));
  const shown = registry.groups.filter((g) => registry.tools.some((t) => t.group === g.name)).map((g) => g.name);
  assert.deepEqual(GROUPS.map((g) => g.name), shown, "the registry's groups in order, those without tools left out");
  assert.deepEqual(GROUPS.flatMap((g) => g.tools.map((t) => t.id)).sort(), TOOLS.map((t) => t.id).sort());
  for (const g of GROUPS) for (const t of g.tools) assert.equal(entry(t.id).group, g.name, t.id);
  for (const t of TOOLS) {
    const r = entry(t.id);
    assert.deepEqual([t.label, t.short, t.key, t.icon, t.color], [r.label, r.browser.short, r.browser.key, r.browser.icon, r.browser.color]);
    assert.deepEqual([...t.takes].sort(), r.params.map((id) => registry.parameters[id].key ?? id).sort(), `${t.id} takes its parameters`);
  }
});

test("a tool's key is one letter of its own, free among the page's keys, and the overlay lists it", () => {
  const keys = TOOLS.map((t) => t.key);
  assert.equal(new Set(keys).size, keys.length, "no two tools share a key");
  for (const t of TOOLS) {
    assert.match(t.key, /^[a-z]$/);
    assert.ok(!PAGE_KEYS.has(t.key), `${t.id}'s key ${t.key} is one of the page's own`);
    const row = KEY_HELP.find(([, what]) => what.startsWith(`${t.group}: `));
    assert.ok(row, `the overlay has a row for ${t.group}`);
    const at = row[0].split(" ").indexOf(t.key.toUpperCase());
    assert.ok(at >= 0, `the overlay lists ${t.id}'s key in its group's row`);
    assert.equal(row[1].slice(t.group.length + 2).split(", ")[at], t.label, `the overlay names ${t.id} in its key's place`);
  }
  for (const k of ["v", "d", "0", "5", "[", "}", "?", "f", " ", "escape", "home"]) assert.ok(PAGE_KEYS.has(k), k);
});

test("tools that stroke are dragged, the others clicked; inverses come in pairs", () => {
  for (const t of TOOLS) {
    assert.equal(t.kind, entry(t.id).strokes ? "stroke" : "click", t.id);
    const inverse = toolWithModifier(t.id, "invert");
    assert.equal(inverse, entry(t.id).inverse ?? t.id, t.id);
    assert.equal(toolWithModifier(inverse, "invert"), t.id, `inverting ${t.id} twice gives it back`);
  }
  assert.equal(toolWithModifier("no_such_tool", "invert"), "no_such_tool");
  assert.equal(toolById("no_such_tool"), TOOLS[0]);
});

test("the whole-volume menu holds the registry's operations, with their first parameter's range", () => {
  assert.deepEqual(Object.keys(GLOBAL_OPS), registry.operations.map((o) => o.name));
  for (const o of registry.operations) {
    const p = registry.parameters[o.params[0]];
    const spec = GLOBAL_OPS[o.name];
    assert.deepEqual([spec.menu, spec.min, spec.max, spec.value, spec.label], [o.label, p.minimum, p.maximum, o.browser.value, o.browser.doing]);
    assert.equal(spec.step, p.type === "integer" ? 1 : "any");
    assert.ok(spec.value >= spec.min && spec.value <= spec.max, `${o.name} starts within its range`);
  }
  assert.equal(GLOBAL_OPS.dilate.amount, "Radius (vu)");
  assert.equal(GLOBAL_OPS.smooth.amount, "Iterations");
});

test("a stroke of a tool that takes a height stands at one; the other brushes accumulate; warps and paint do neither", () => {
  for (const t of registry.tools.filter((x) => x.strokes)) {
    const params = strokeBeginParams({ tool: t.name, radius: 8, strength: 1 });
    // Paint and mask remember their dabs (the same spot twice is once) unless built up.
    if (t.kind === "warp" || t.kind === "paint") assert.deepEqual([params.height, params.accumulate], [undefined, undefined], t.name);
    else if (t.params.includes("height")) assert.equal(params.height, 4, t.name);
    else assert.deepEqual([params.height, params.accumulate], [undefined, true], t.name);
  }
});

test("a warp's gesture is its registry dabs; the other tools have none", () => {
  for (const t of TOOLS) assert.equal(t.warp, entry(t.id).kind === "warp" ? entry(t.id).dabs ?? "swept" : null, t.id);
});

test("a tool's radius range is its radius parameter's, which the brush slider keeps to", () => {
  for (const t of TOOLS) {
    const p = entry(t.id).params.map((id) => ({ id, ...registry.parameters[id] })).find((q) => (q.key ?? q.id) === "radius");
    assert.deepEqual(t.radiusRange, p ? [p.minimum, p.maximum] : null, t.id);
  }
  assert.deepEqual(toolById("add_blob").radiusRange, [0.5, 1024]);
});

test("tools are named in sentences as the palette names them", () => {
  assert.equal(toolName("add_blob"), "add blob");
  assert.equal(toolName("csg_intersect"), "CSG intersect");
  assert.equal(toolName("some_new_tool"), "some new tool");
});
