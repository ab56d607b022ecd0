// Vertex colours of `marzipan batch --out x.ply / x.glb` read by readers that are not ours:
// @loaders.gl/ply for the PLY, glTF Transform (@gltf-transform/core) for the glb, whose document
// the Khronos validator also checks (pinned by package-lock.json). The clay comes from a
// two-coloured box this test writes as an OBJ (red top, blue bottom, sides shading between),
// loaded with --load: the same files a painted session exports. A .glb written so is loaded
// again (--load x.glb) and its .ply read the same way.
// Run by ctest through run.sh, which refuses (never skips) without its packages or marzipan.
import { test } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import validator from "gltf-validator";
import { NodeIO } from "@gltf-transform/core";
import { parse } from "@loaders.gl/core";
import { PLYLoader } from "@loaders.gl/ply";

const marzipan = process.env.MARZIPAN;
const work = mkdtempSync(join(tmpdir(), "marzipan-colors-"));
const lo = [10.5, 11.25, 9.75];
const hi = [40.25, 38.5, 41.5];

// The box as an OBJ with "v x y z r g b" (0..1): corners with the top's z red, the others blue.
function boxObj() {
  let s = "";
  for (let c = 0; c < 8; ++c) {
    const p = [c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]];
    s += `v ${p.join(" ")} ${c & 4 ? "1 0 0" : "0 0 1"}\n`;
  }
  const f = [0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5];
  for (let t = 0; t < f.length; t += 3) s += `f ${f[t] + 1} ${f[t + 1] + 1} ${f[t + 2] + 1}\n`;
  return s;
}

const box = join(work, "box.obj");
writeFileSync(box, boxObj());
const ops = join(work, "none.jsonl");
writeFileSync(ops, "");

// The file `marzipan batch --load from --size 52 ...args --out name` writes.
function exported(name, args = [], from = box) {
  const out = join(work, name);
  execFileSync(marzipan, ["batch", ops, "--load", from, "--size", "52", ...args, "--out", out], { stdio: ["ignore", "pipe", "inherit"] });
  return readFileSync(out);
}

// The sRGB byte of a linear value (IEC 61966-2-1): COLOR_0 is linear light.
function srgbByte(linear) {
  const s = linear <= 0.0031308 ? 12.92 * linear : 1.055 * Math.pow(linear, 1 / 2.4) - 0.055;
  return Math.round(255 * s);
}

async function readPly(bytes) {
  const mesh = await parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), PLYLoader);
  return { positions: mesh.attributes.POSITION.value, colors: mesh.attributes.COLOR_0.value };
}

// Red on the top face, blue on the bottom, red + blue = 255 and no green anywhere.
function checkBoxColors({ positions, colors }) {
  assert.equal(colors.length, positions.length);  // red, green, blue per vertex
  let top = 0, bottom = 0;
  const inner = (v) => [0, 1].every((a) => positions[3 * v + a] > lo[a] + 3 && positions[3 * v + a] < hi[a] - 3);
  for (let v = 0; v < positions.length / 3; ++v) {
    const [r, g, b] = colors.slice(3 * v, 3 * v + 3);
    assert.equal(g, 0, `vertex ${v}`);
    assert.ok(Math.abs(r + b - 255) <= 1, `vertex ${v}: ${r} ${g} ${b}`);
    const z = positions[3 * v + 2];
    if (inner(v) && Math.abs(z - hi[2]) < 0.01) ++top, assert.deepEqual([r, g, b], [255, 0, 0], `top vertex ${v}`);
    if (inner(v) && Math.abs(z - lo[2]) < 0.01) ++bottom, assert.deepEqual([r, g, b], [0, 0, 255], `bottom vertex ${v}`);
  }
  assert.ok(top > 200 && bottom > 200, `${top} top and ${bottom} bottom vertices`);
}

test("PLY vertex colours: red on the top face, blue on the bottom, red + blue = 255 and no green anywhere", async () => {
  checkBoxColors(await readPly(exported("box.ply")));
});

test("a .glb loaded with --load keeps its colours: its .ply shows the same box", async () => {
  writeFileSync(join(work, "box-loaded.glb"), exported("box-to-load.glb"));
  checkBoxColors(await readPly(exported("box-from-glb.ply", [], join(work, "box-loaded.glb"))));
});

test("a .glb's COLOR_0 passes the validator and holds, in linear light, the PLY's colours", async () => {
  const ply = await readPly(exported("box-for-glb.ply"));
  const bytes = new Uint8Array(exported("box.glb"));
  const report = await validator.validateBytes(bytes, { maxIssues: 20 });
  const shown = report.issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer ?? ""}: ${m.message}`);
  assert.equal(report.issues.numErrors, 0, shown.join("\n"));
  assert.equal(report.issues.numWarnings, 0, shown.join("\n"));

  const doc = await new NodeIO().readBinary(bytes);
  const primitive = doc.getRoot().listMeshes()[0].listPrimitives()[0];
  const color = primitive.getAttribute("COLOR_0");
  assert.equal(color.getType(), "VEC3");
  assert.equal(color.getComponentType(), 5126);  // float
  assert.deepEqual(Array.from(primitive.getAttribute("POSITION").getArray()), Array.from(ply.positions));
  const linear = color.getArray();
  let wrong = 0;
  for (let i = 0; i < linear.length; ++i) wrong += srgbByte(linear[i]) === ply.colors[i] ? 0 : 1;
  assert.equal(wrong, 0, `${wrong} of ${linear.length} channels differ from the PLY's`);
});

test("a decimated coloured .glb passes the validator", async () => {
  const bytes = new Uint8Array(exported("decimated.glb", ["--max-triangles", "500"]));
  const report = await validator.validateBytes(bytes, { maxIssues: 20 });
  assert.equal(report.issues.numErrors + report.issues.numWarnings, 0);
  const primitive = (await new NodeIO().readBinary(bytes)).getRoot().listMeshes()[0].listPrimitives()[0];
  assert.ok(primitive.getIndices().getCount() / 3 <= 500);
  assert.equal(primitive.getAttribute("COLOR_0").getCount(), primitive.getAttribute("POSITION").getCount());
});
