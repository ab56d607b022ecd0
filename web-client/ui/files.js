// Files in and out of the page: downloads of what the server sends (meshes, volume files) and
// of snapshots, and reading a file the person picks.

const MIME = { stl: "model/stl", obj: "model/obj", ply: "application/octet-stream", glb: "model/gltf-binary", mzv: "application/octet-stream", vdb: "application/octet-stream", png: "image/png" };

// The volume format of a picked file, by its extension: "vdb" for .vdb, else "mzv".
export function volumeFormatOf(name) {
  return /\.vdb$/i.test(name) ? "vdb" : "mzv";
}

// Offers `data` (a Blob, or bytes) as a download named `name`.
export function download(data, name) {
  const ext = name.slice(name.lastIndexOf(".") + 1);
  const blob = data instanceof Blob ? data : new Blob([data], { type: MIME[ext] || "application/octet-stream" });
  const url = URL.createObjectURL(blob);
  const a = document.createElement("a");
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
}

// "marzipan-SESSION-rREVISION.EXT": names that sort by session and revision.
export function fileName(session, revision, ext) {
  return `marzipan-${session.slice(0, 8)}-r${revision}.${ext}`;
}

// The bytes of a File as a Uint8Array.
export async function readFile(file) {
  return new Uint8Array(await file.arrayBuffer());
}
