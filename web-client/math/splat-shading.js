// Linearly varying normals over splat discs ("Phong splatting", Botsch, Spernat and Kobbelt,
// 2004): a disc with one flat normal paints that normal over its whole footprint, so where the
// surface bends fast (a groove's rim, the pig's snout and feet: bevels a voxel or two wide) the
// neighbouring discs' normals differ a lot and each disc shows as a bead, however they are
// blended. Each disc instead gets the rate of change of the normal across it, fitted to its
// neighbours', and draws n(x) = n + u dn/du + v dn/dv at the point x = p + u t + v b of the
// disc: at its edge it already shows what its neighbours show, and the rim shades smoothly.
//
// Conventions: vu; points and normals as the store has them (render/splat-store.js: a brick
// (bx, by, bz) holds points within [8b - 2, 8b + 10) per axis, unit normals). The disc's frame
// is the one the vertex shader builds (render/splat-renderer.js): t = normalize(h x n), b =
// n x t, h = +y unless |n.y| >= 0.9, then +x. Per point six numbers: dn/du then dn/dv (per vu,
// world axes), the least-squares fit of m - n = u dn/du + v dn/dv over the neighbours q
// (normal m) within NEIGHBOURHOOD vu, (u, v) = ((q - p).t, (q - p).b), each weighted by
// (1 - (d / NEIGHBOURHOOD)^2)^2; a disc with fewer than three neighbours, or whose neighbours
// lie along one line (a singular fit), keeps a flat normal (zeros), and so does one whose
// normal would turn by less than MIN_TURN across its radius (invisible; a flat disc costs the
// vertex shader one texel fetch less, and a large smooth model such as the 256^3 sphere has
// only those). The gradient is clamped to MAX_GRADIENT per vu (the GPU texture's range,
// render/splat-buffer.js).

export const NEIGHBOURHOOD = 1.6; // vu: two disc radii, the discs that overlap this one
export const MAX_GRADIENT = 2; // per vu: a bend of radius 0.5 vu
export const MIN_TURN = 0.03; // radians (1.7 degrees) across a disc's radius
// Normals within this angle of each other everywhere in a brick and its surroundings
// (cos 1 degree): no disc could turn by MIN_TURN (the fit is a weighted mean of the normals'
// differences over distances of at least ~0.5 vu), skip the fit.
const FLAT_COS = Math.cos(Math.PI / 180);
const DISC_RADIUS = 0.8; // render/splat-store.js (which imports this module)
const BRICK = 8;
const MARGIN = 4; // cells of the local grid beyond the brick: the points' reach (2) + the neighbourhood
const SIDE = BRICK + 2 * MARGIN;

const head = new Int32Array(SIDE * SIDE * SIDE);
let next = new Int32Array(0);
let xyz = new Float32Array(0); // gathered points: x, y, z, nx, ny, nz
let capacity = 0;

function reserve(n) {
  if (n <= capacity) return;
  capacity = Math.max(n, Math.ceil(capacity * 1.5), 1024);
  next = new Int32Array(capacity);
  xyz = new Float32Array(6 * capacity);
}

// The disc frame of the shader: [t, b] for the unit normal n.
export function discFrame(n) {
  const h = Math.abs(n[1]) < 0.9 ? [0, 1, 0] : [1, 0, 0];
  let t = [h[1] * n[2] - h[2] * n[1], h[2] * n[0] - h[0] * n[2], h[0] * n[1] - h[1] * n[0]];
  const len = Math.hypot(...t);
  t = t.map((x) => x / len);
  const b = [n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]];
  return [t, b];
}

// The normal gradients of every point of `entry` ({brick, count, positions, normals}), given the
// bricks that may hold its neighbours (`around`: entries of the same shape, `entry` among them;
// points farther than one brick away are ignored). Returns a Float32Array of 6 numbers per
// point (dn/du, dn/dv), or null when every disc of the brick keeps a flat normal; `radius`
// the discs' (vu).
export function normalGradients(entry, around, radius = DISC_RADIUS) {
  const ox = BRICK * entry.brick[0] - MARGIN, oy = BRICK * entry.brick[1] - MARGIN, oz = BRICK * entry.brick[2] - MARGIN;
  let total = 0;
  for (const b of around) total += b.count;
  reserve(total);
  head.fill(-1);
  let k = 0;
  let self = -1; // index of entry's first point among the gathered ones
  for (const b of around) {
    const p = b.positions, n = b.normals;
    if (b === entry) self = k;
    for (let i = 0; i < 3 * b.count; i += 3) {
      let cx = Math.floor(p[i] - ox), cy = Math.floor(p[i + 1] - oy), cz = Math.floor(p[i + 2] - oz);
      if (cx < 0 || cy < 0 || cz < 0 || cx >= SIDE || cy >= SIDE || cz >= SIDE) {
        if (b !== entry) continue;
        [cx, cy, cz] = [clampCell(cx), clampCell(cy), clampCell(cz)]; // (the server keeps them within)
      }
      const o = 6 * k;
      for (let c = 0; c < 3; ++c) {
        xyz[o + c] = p[i + c];
        xyz[o + 3 + c] = n[i + c];
      }
      const cell = cellOf(cx, cy, cz);
      next[k] = head[cell];
      head[cell] = k;
      ++k;
    }
  }
  if (k === 0 || flat(k)) return null;
  const out = new Float32Array(6 * entry.count);
  let any = false;
  const reach2 = NEIGHBOURHOOD * NEIGHBOURHOOD;
  const ru = [0, 0, 0], rv = [0, 0, 0];
  for (let i = 0; i < entry.count; ++i) {
    const s = 6 * (self + i);
    const px = xyz[s], py = xyz[s + 1], pz = xyz[s + 2];
    const nx = xyz[s + 3], ny = xyz[s + 4], nz = xyz[s + 5];
    // the shader's frame (discFrame), written out: t = normalize(h x n), b = n x t
    const hy = Math.abs(ny) < 0.9;
    let tx = hy ? nz : 0, ty = hy ? 0 : -nz, tz = hy ? -nx : ny;
    const tl = Math.hypot(tx, ty, tz);
    tx /= tl;
    ty /= tl;
    tz /= tl;
    const bx = ny * tz - nz * ty, by = nz * tx - nx * tz, bz = nx * ty - ny * tx;
    // Normal equations of the weighted fit: A [g_u; g_v] = r, per world axis.
    let auu = 0, auv = 0, avv = 0, used = 0;
    ru.fill(0);
    rv.fill(0);
    const x0 = clampCell(Math.floor(px - NEIGHBOURHOOD - ox)), x1 = clampCell(Math.floor(px + NEIGHBOURHOOD - ox));
    const y0 = clampCell(Math.floor(py - NEIGHBOURHOOD - oy)), y1 = clampCell(Math.floor(py + NEIGHBOURHOOD - oy));
    const z0 = clampCell(Math.floor(pz - NEIGHBOURHOOD - oz)), z1 = clampCell(Math.floor(pz + NEIGHBOURHOOD - oz));
    for (let cz = z0; cz <= z1; ++cz)
      for (let cy = y0; cy <= y1; ++cy)
        for (let cx = x0, cell = cellOf(x0, cy, cz); cx <= x1; ++cx, ++cell)
          for (let q = head[cell]; q >= 0; q = next[q]) {
            const o = 6 * q;
            const dx = xyz[o] - px, dy = xyz[o + 1] - py, dz = xyz[o + 2] - pz;
            const d2 = dx * dx + dy * dy + dz * dz;
            if (d2 >= reach2 || o === s) continue;
            const w = (1 - d2 / reach2) ** 2;
            const u = dx * tx + dy * ty + dz * tz, v = dx * bx + dy * by + dz * bz;
            auu += w * u * u;
            auv += w * u * v;
            avv += w * v * v;
            const mx = xyz[o + 3] - nx, my = xyz[o + 4] - ny, mz = xyz[o + 5] - nz;
            ru[0] += w * u * mx;
            ru[1] += w * u * my;
            ru[2] += w * u * mz;
            rv[0] += w * v * mx;
            rv[1] += w * v * my;
            rv[2] += w * v * mz;
            ++used;
          }
    const det = auu * avv - auv * auv;
    if (used < 3 || det <= 1e-6 * (auu + avv) * (auu + avv)) continue;
    let largest = 0;
    for (let c = 0; c < 3; ++c) {
      out[6 * i + c] = clampGradient((avv * ru[c] - auv * rv[c]) / det);
      out[6 * i + 3 + c] = clampGradient((auu * rv[c] - auv * ru[c]) / det);
      largest = Math.max(largest, Math.abs(out[6 * i + c]), Math.abs(out[6 * i + 3 + c]));
    }
    if (largest * radius < MIN_TURN) out.fill(0, 6 * i, 6 * i + 6);
    else any = true;
  }
  return any ? out : null;
}

function clampGradient(g) {
  return Math.max(-MAX_GRADIENT, Math.min(MAX_GRADIENT, g));
}

// Whether the k gathered normals all lie within half of FLAT_COS's angle of their mean, so
// that no two differ by more than it (the angles between unit vectors obey the triangle
// inequality).
function flat(k) {
  let sx = 0, sy = 0, sz = 0;
  for (let o = 0; o < 6 * k; o += 6) {
    sx += xyz[o + 3];
    sy += xyz[o + 4];
    sz += xyz[o + 5];
  }
  const len = Math.hypot(sx, sy, sz);
  if (len === 0) return false;
  const limit = Math.sqrt((1 + FLAT_COS) / 2) * len;
  for (let o = 0; o < 6 * k; o += 6) if (xyz[o + 3] * sx + xyz[o + 4] * sy + xyz[o + 5] * sz < limit) return false;
  return true;
}

function cellOf(x, y, z) {
  return x + SIDE * (y + SIDE * z);
}

function clampCell(c) {
  return Math.max(0, Math.min(SIDE - 1, c));
}
