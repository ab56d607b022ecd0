// `marzipan batch --out x.glb` checked by the Khronos glTF validator (npm gltf-validator, pinned
// by package-lock.json): no errors and no warnings, and the document holds what was exported.
// Run by ctest through run.sh, which refuses (never skips) without the validator or marzipan.
import { test } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import validator from "gltf-validator";

const marzipan = process.env.MARZIPAN;
const work = mkdtempSync(join(tmpdir(), "marzipan-gltf-"));

// Runs `marzipan batch` with no operations and the given options; returns the .glb's bytes
// and what the command printed.
function exportGlb(name, args) {
  const ops = join(work, "none.jsonl");
  writeFileSync(ops, "");
  const out = join(work, `${name}.glb`);
  const stdout = execFileSync(marzipan, ["batch", ops, ...args, "--out", out], { stdio: ["ignore", "pipe", "inherit"] });
  const bytes = new Uint8Array(readFileSync(out));
  bytes.stdout = stdout.toString();
  return bytes;
}

async function validate(bytes) {
  const report = await validator.validateBytes(bytes, { maxIssues: 20 });
  const shown = report.issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer ?? ""}: ${m.message}`);
  assert.equal(report.issues.numErrors, 0, shown.join("\n"));
  assert.equal(report.issues.numWarnings, 0, shown.join("\n"));
  return report;
}

// The JSON chunk of a .glb (chunk 0, right after the 12-byte header).
function gltfJson(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  assert.equal(view.getUint32(0, true), 0x46546c67);
  assert.equal(view.getUint32(4, true), 2);
  assert.equal(view.getUint32(8, true), bytes.length);
  const length = view.getUint32(12, true);
  return JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
}

test("the pig's mesh with normals passes the validator", async () => {
  const bytes = exportGlb("pig", ["--solid", "pig", "--size", "96"]);
  const report = await validate(bytes);
  const doc = gltfJson(bytes);
  const primitive = doc.meshes[0].primitives[0];
  assert.ok("NORMAL" in primitive.attributes);
  const triangles = doc.accessors[primitive.indices].count / 3;
  assert.ok(triangles > 10000, `${triangles} triangles`);
  assert.equal(report.info.totalTriangleCount, triangles);
  assert.equal(report.info.totalVertexCount, doc.accessors[primitive.attributes.POSITION].count);
});

test("a sphere's bounding box is its accessor's min and max", async () => {
  const bytes = exportGlb("sphere", ["--solid", "sphere", "--size", "64"]);
  await validate(bytes);
  const doc = gltfJson(bytes);
  const position = doc.accessors[doc.meshes[0].primitives[0].attributes.POSITION];
  // makeSphere in N^3 is centred at (N-1)/2 with radius 0.35 N (server/engine/solids.hpp).
  for (let a = 0; a < 3; ++a) {
    assert.ok(Math.abs(position.min[a] - (31.5 - 22.4)) < 0.1, `min ${position.min}`);
    assert.ok(Math.abs(position.max[a] - (31.5 + 22.4)) < 0.1, `max ${position.max}`);
  }
});

test("a decimated sphere passes the validator and holds the reported triangle count", async () => {
  const bytes = exportGlb("decimated", ["--solid", "sphere", "--size", "128", "--max-triangles", "20000"]);
  const report = await validate(bytes);
  const printed = JSON.parse(bytes.stdout);
  assert.ok(printed.source_triangles > 70000, bytes.stdout);
  assert.ok(printed.triangles <= 20000 && printed.triangles > 19000, bytes.stdout);
  assert.ok(printed.max_error > 0 && printed.max_error < 0.3, bytes.stdout);
  assert.equal(report.info.totalTriangleCount, printed.triangles);
  assert.equal(report.info.totalVertexCount, printed.vertices);
});

test("an empty solid is a valid file with an empty scene", async () => {
  const bytes = exportGlb("empty", ["--solid", "empty", "--size", "16"]);
  await validate(bytes);
  const doc = gltfJson(bytes);
  assert.equal(doc.meshes, undefined);
  assert.deepEqual(doc.scenes, [{}]);
});
