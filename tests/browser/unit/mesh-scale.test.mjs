// web-client/math/mesh-scale.js: mesh files rescaled from vu to millimetres (metres for GLB),
// on files laid out as server/engine/mesh_io.cpp and gltf.cpp write them.
import { test } from "node:test";
import assert from "node:assert/strict";

import { scaleMesh } from "../../../web-client/math/mesh-scale.js";

// One triangle, (1, 2, 3), (4.5, 0, 7), (10, 20, 30.25) vu, normal (0, 0, 1).
const V = [[1, 2, 3], [4.5, 0, 7], [10, 20, 30.25]];
const f32 = (x) => Math.fround(x);

function stl() {
  const b = new Uint8Array(84 + 50);
  const d = new DataView(b.buffer);
  d.setUint32(80, 1, true);
  d.setFloat32(84 + 8, 1, true);
  V.flat().forEach((v, i) => d.setFloat32(84 + 12 + 4 * i, v, true));
  return b;
}

test("STL: every vertex scales, the normal and the layout stay", () => {
  const out = scaleMesh("stl", stl(), 0.25);
  const d = new DataView(out.buffer);
  assert.equal(out.length, 134);
  assert.equal(d.getFloat32(84 + 8, true), 1);
  V.flat().forEach((v, i) => assert.equal(d.getFloat32(84 + 12 + 4 * i, true), f32(v * 0.25)));
  assert.throws(() => scaleMesh("stl", stl().subarray(0, 120), 2), /not a binary STL/);
});

test("OBJ: v lines scale, vn and faces stay, a comment gives the unit", () => {
  const text = `# Marzipan mesh\n${V.map((v) => `v ${v.join(" ")}`).join("\n")}\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1//1 2//2 3//3\n`;
  const out = new TextDecoder().decode(scaleMesh("obj", new TextEncoder().encode(text), 2));
  assert.equal(out, `# units: mm (2 mm per vu)\n# Marzipan mesh\nv 2 4 6\nv 9 0 14\nv 20 40 60.5\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1//1 2//2 3//3\n`);
});

test("PLY: x, y, z of each vertex scale, the normals and faces stay, the header says mm", () => {
  const header = "ply\nformat binary_little_endian 1.0\ncomment Marzipan mesh\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n";
  const h = new TextEncoder().encode(header);
  const body = new Uint8Array(3 * 24 + 13);
  const d = new DataView(body.buffer);
  V.forEach((v, i) => [...v, 0, 0, 1].forEach((x, k) => d.setFloat32(24 * i + 4 * k, x, true)));
  body[72] = 3;
  [0, 1, 2].forEach((x, k) => d.setUint32(73 + 4 * k, x, true));
  const file = new Uint8Array(h.length + body.length);
  file.set(h);
  file.set(body, h.length);
  const out = scaleMesh("ply", file, 0.1);
  const text = new TextDecoder("latin1").decode(out);
  const end = text.indexOf("end_header\n") + 11;
  assert.match(text.slice(0, end), /^ply\nformat binary_little_endian 1\.0\ncomment units: mm \(0\.1 mm per vu\)\n/);
  const o = new DataView(out.buffer, end);
  V.forEach((v, i) => {
    v.forEach((x, k) => assert.equal(o.getFloat32(24 * i + 4 * k, true), f32(f32(x) * 0.1)));
    assert.equal(o.getFloat32(24 * i + 20, true), 1);
  });
  assert.deepEqual([...out.subarray(end + 72)], [...body.subarray(72)], "the faces are the same bytes");
  assert.throws(() => scaleMesh("ply", new TextEncoder().encode("ply\nformat ascii 1.0\nend_header\n"), 1), /binary little-endian/);
});

test("GLB: positions and their min/max become metres (mm / 1000), the rest is the same bytes", () => {
  const bin = new Uint8Array(36 + 36 + 12);
  const d = new DataView(bin.buffer);
  V.flat().forEach((v, i) => d.setFloat32(4 * i, v, true));
  [0, 0, 1, 0, 0, 1, 0, 0, 1].forEach((v, i) => d.setFloat32(36 + 4 * i, v, true));
  [0, 1, 2].forEach((v, i) => d.setUint32(72 + 4 * i, v, true));
  const gltf = {
    asset: { version: "2.0", generator: "Marzipan" },
    meshes: [{ primitives: [{ attributes: { POSITION: 0, NORMAL: 1 }, indices: 2 }] }],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 3, type: "VEC3", min: [1, 0, 3], max: [10, 20, 30.25] },
      { bufferView: 1, componentType: 5126, count: 3, type: "VEC3" },
      { bufferView: 2, componentType: 5125, count: 3, type: "SCALAR" },
    ],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: 36 }, { buffer: 0, byteOffset: 36, byteLength: 36 }, { buffer: 0, byteOffset: 72, byteLength: 12 }],
    buffers: [{ byteLength: 84 }],
  };
  let json = JSON.stringify(gltf);
  json += " ".repeat((4 - (json.length % 4)) % 4);
  const file = new Uint8Array(20 + json.length + 8 + bin.length);
  const fv = new DataView(file.buffer);
  fv.setUint32(0, 0x46546c67, true);
  fv.setUint32(4, 2, true);
  fv.setUint32(8, file.length, true);
  fv.setUint32(12, json.length, true);
  fv.setUint32(16, 0x4e4f534a, true);
  file.set(new TextEncoder().encode(json), 20);
  fv.setUint32(20 + json.length, bin.length, true);
  fv.setUint32(24 + json.length, 0x004e4942, true);
  file.set(bin, 28 + json.length);

  const out = scaleMesh("glb", file, 0.5); // 0.5 mm per vu = 0.0005 m per vu
  const ov = new DataView(out.buffer);
  assert.equal(ov.getUint32(8, true), out.length);
  const jsonLength = ov.getUint32(12, true);
  assert.equal(jsonLength % 4, 0);
  const g = JSON.parse(new TextDecoder().decode(out.subarray(20, 20 + jsonLength)));
  assert.deepEqual(g.accessors[0].min, [1, 0, 3].map((x) => f32(x * 0.0005)));
  assert.deepEqual(g.accessors[0].max, [10, 20, 30.25].map((x) => f32(x * 0.0005)));
  assert.equal(g.asset.extras.mm_per_vu, 0.5);
  const ob = new DataView(out.buffer, 28 + jsonLength);
  V.flat().forEach((v, i) => assert.equal(ob.getFloat32(4 * i, true), f32(v * 0.0005)));
  assert.deepEqual([...out.subarray(28 + jsonLength + 36)], [...bin.subarray(36)], "normals and indices are the same bytes");
});

test("a scale that is not a positive number is refused", () => {
  for (const s of [0, -1, NaN, Infinity]) assert.throws(() => scaleMesh("stl", stl(), s), RangeError);
});
