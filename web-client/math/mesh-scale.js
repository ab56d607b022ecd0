// Mesh files in millimetres: the server writes meshes in vu (PROTOCOL.md, mesh.export); the
// page rescales the file it receives by the chosen millimetres per vu before offering it, so
// a print comes out at the size the sculptor asked for.
// Conventions: STL, OBJ and PLY carry no unit, so their coordinates become millimetres; glTF's
// unit is the metre, so a GLB's positions become metres (mm / 1000). Only positions change:
// normals are unit vectors and a uniform scale keeps their direction. The input is the file as
// server/engine/mesh_io.cpp and gltf.cpp write it: binary STL, OBJ text, binary little-endian
// PLY whose vertex element has float x, y, z, glTF 2.0 binary with float POSITION accessors.
// A file of any other layout is refused with an Error rather than scaled wrongly.

// The file `bytes` (Uint8Array) of `format` (stl, obj, ply, glb) with its positions multiplied
// by `mmPerVu` (> 0, finite); a new Uint8Array, the input untouched.
export function scaleMesh(format, bytes, mmPerVu) {
  if (!(mmPerVu > 0 && Number.isFinite(mmPerVu))) throw new RangeError(`the scale must be a positive number of mm per vu, got ${mmPerVu}`);
  switch (format) {
    case "stl":
      return scaleStl(bytes, mmPerVu);
    case "obj":
      return scaleObj(bytes, mmPerVu);
    case "ply":
      return scalePly(bytes, mmPerVu);
    case "glb":
      return scaleGlb(bytes, mmPerVu / 1000);
    default:
      throw new Error(`no scaling for mesh format ${format}`);
  }
}

// Binary STL: 80-byte header, u32 n, n records of 50 bytes (normal, three vertices, u16).
function scaleStl(bytes, s) {
  const out = bytes.slice();
  const view = new DataView(out.buffer, out.byteOffset, out.byteLength);
  if (out.length < 84) throw new Error("not a binary STL: shorter than its 84-byte header");
  const n = view.getUint32(80, true);
  if (out.length !== 84 + 50 * n) throw new Error(`not a binary STL: ${out.length} bytes for ${n} triangles`);
  for (let t = 0; t < n; ++t)
    for (let k = 3; k < 12; ++k) {
      const at = 84 + 50 * t + 4 * k;
      view.setFloat32(at, view.getFloat32(at, true) * s, true);
    }
  return out;
}

// OBJ text: "v x y z" lines scale; a comment line says the unit.
function scaleObj(bytes, s) {
  const lines = new TextDecoder().decode(bytes).split("\n");
  const scaled = lines.map((line) => {
    if (!line.startsWith("v ")) return line;
    const parts = line.trim().split(/\s+/);
    return ["v", ...parts.slice(1).map((v, i) => (i < 3 ? formatFloat(Number(v) * s) : v))].join(" ");
  });
  return new TextEncoder().encode(`# units: mm (${s} mm per vu)\n${scaled.join("\n")}`);
}

const PLY_SIZES = { char: 1, uchar: 1, int8: 1, uint8: 1, short: 2, ushort: 2, int16: 2, uint16: 2, int: 4, uint: 4, int32: 4, uint32: 4, float: 4, float32: 4, double: 8, float64: 8 };

// Binary little-endian PLY whose first element is the vertices, with float x, y, z among
// fixed-size properties; a comment line says the unit.
function scalePly(bytes, s) {
  const head = new TextDecoder("latin1").decode(bytes.subarray(0, Math.min(bytes.length, 4096)));
  const end = head.indexOf("end_header\n");
  if (!head.startsWith("ply\n") || end < 0) throw new Error("not a PLY file with an end_header line");
  const lines = head.slice(0, end - 1).split("\n"); // without the newline before end_header
  if (!lines.includes("format binary_little_endian 1.0")) throw new Error("not a binary little-endian PLY");
  const vertexLine = lines.findIndex((l) => l.startsWith("element "));
  const [, name, countText] = lines[vertexLine].split(" ");
  if (name !== "vertex") throw new Error("the PLY's first element is not its vertices");
  const count = Number(countText);
  let stride = 0;
  const xyz = {};
  for (let i = vertexLine + 1; i < lines.length && lines[i].startsWith("property "); ++i) {
    const [, type, prop] = lines[i].split(" ");
    if (!(type in PLY_SIZES)) throw new Error(`PLY vertex property of type ${type}`);
    if (["x", "y", "z"].includes(prop)) {
      if (PLY_SIZES[type] !== 4 || !type.startsWith("float")) throw new Error(`PLY coordinate ${prop} is not a float`);
      xyz[prop] = stride;
    }
    stride += PLY_SIZES[type];
  }
  if (Object.keys(xyz).length !== 3) throw new Error("the PLY's vertices lack x, y or z");
  const bodyStart = end + "end_header\n".length;
  const header = [lines[0], lines[1], `comment units: mm (${s} mm per vu)`, ...lines.slice(2), "end_header", ""].join("\n");
  const headerBytes = new TextEncoder().encode(header);
  const out = new Uint8Array(headerBytes.length + bytes.length - bodyStart);
  out.set(headerBytes);
  out.set(bytes.subarray(bodyStart), headerBytes.length);
  if (out.length < headerBytes.length + count * stride) throw new Error("the PLY is shorter than its vertices");
  const view = new DataView(out.buffer, out.byteOffset, out.byteLength);
  for (let v = 0; v < count; ++v)
    for (const off of [xyz.x, xyz.y, xyz.z]) {
      const at = headerBytes.length + v * stride + off;
      view.setFloat32(at, view.getFloat32(at, true) * s, true);
    }
  return out;
}

const GLB_MAGIC = 0x46546c67; // "glTF"
const CHUNK_JSON = 0x4e4f534a;
const CHUNK_BIN = 0x004e4942;
const FLOAT = 5126;

// glTF 2.0 binary: every accessor used as a POSITION scales, data and min/max; the JSON chunk
// is written again (padded with spaces to 4 bytes), the binary chunk keeps its layout.
function scaleGlb(bytes, s) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (bytes.length < 20 || view.getUint32(0, true) !== GLB_MAGIC || view.getUint32(4, true) !== 2) throw new Error("not a glTF 2.0 binary");
  const jsonLength = view.getUint32(12, true);
  if (view.getUint32(16, true) !== CHUNK_JSON) throw new Error("the GLB's first chunk is not JSON");
  const gltf = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const rest = bytes.slice(20 + jsonLength); // the BIN chunk, header included, or nothing
  const positions = new Set();
  for (const mesh of gltf.meshes || []) for (const p of mesh.primitives || []) if (p.attributes && p.attributes.POSITION !== undefined) positions.add(p.attributes.POSITION);
  if (positions.size && (rest.length < 8 || new DataView(rest.buffer).getUint32(4, true) !== CHUNK_BIN)) throw new Error("the GLB has positions but no binary chunk");
  const bin = new DataView(rest.buffer, 8);
  for (const index of positions) {
    const acc = gltf.accessors[index];
    const bufferView = gltf.bufferViews[acc.bufferView];
    if (acc.componentType !== FLOAT || acc.type !== "VEC3" || acc.sparse || bufferView.buffer !== 0) throw new Error("a GLB POSITION accessor that is not plain float VEC3 data");
    const stride = bufferView.byteStride || 12;
    const base = (bufferView.byteOffset || 0) + (acc.byteOffset || 0);
    for (let v = 0; v < acc.count; ++v)
      for (let k = 0; k < 3; ++k) {
        const at = base + v * stride + 4 * k;
        bin.setFloat32(at, bin.getFloat32(at, true) * s, true);
      }
    if (acc.min) acc.min = acc.min.map((x) => Math.fround(x * s));
    if (acc.max) acc.max = acc.max.map((x) => Math.fround(x * s));
  }
  gltf.asset = { ...gltf.asset, extras: { ...(gltf.asset && gltf.asset.extras), mm_per_vu: s * 1000 } };
  let json = JSON.stringify(gltf);
  json += " ".repeat((4 - (new TextEncoder().encode(json).length % 4)) % 4);
  const jsonBytes = new TextEncoder().encode(json);
  const out = new Uint8Array(20 + jsonBytes.length + rest.length);
  const outView = new DataView(out.buffer);
  outView.setUint32(0, GLB_MAGIC, true);
  outView.setUint32(4, 2, true);
  outView.setUint32(8, out.length, true);
  outView.setUint32(12, jsonBytes.length, true);
  outView.setUint32(16, CHUNK_JSON, true);
  out.set(jsonBytes, 20);
  out.set(rest, 20 + jsonBytes.length);
  return out;
}

// Nine significant digits: a float32 written so that reading it back gives the same float.
function formatFloat(v) {
  return String(Number(Math.fround(v).toPrecision(9)));
}
