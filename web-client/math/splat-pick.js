// Picking: the first splat disc that a ray meets, on the client's own copy of the splats.
// It finds exactly what the splat view draws (the same discs, front faces only), costs
// microseconds (only bricks whose box the ray crosses are searched, nearest first) and never
// waits for the GPU.
// Conventions: vu, y up; a brick (bx, by, bz) holds points within [8b - 2, 8b + 10) per axis
// (server/engine/splats.hpp); `bricks` is an iterable of {brick: [bx, by, bz], count,
// positions, normals, colors?} with x, y, z per point in the Float32Arrays and r, g, b, mask
// per point in `colors` (protocol/js/splats.js); `direction` unit length.

const BRICK = 8;
const REACH_LO = -2; // the encodable range of a brick's points, relative to 8 * brick
const REACH_HI = 10;

// {t, point, normal, color} of the nearest front-facing disc of radius `discRadius` hit by the
// ray origin + t direction (t >= 0), or null; color is the disc's [r, g, b] (sRGB bytes), null
// when its brick has no colours.
export function pickSplats(bricks, origin, direction, discRadius) {
  const [ox, oy, oz] = origin;
  const [dx, dy, dz] = direction;
  const inv = [1 / dx, 1 / dy, 1 / dz];
  const candidates = [];
  for (const b of bricks) {
    if (b.count === 0) continue;
    const enter = enterBrick(origin, inv, b.brick, discRadius);
    if (enter !== null) candidates.push({ enter, b });
  }
  candidates.sort((a, c) => a.enter - c.enter);
  const r2 = discRadius * discRadius;
  let best = Infinity;
  let bestIndex = -1;
  let bestBrick = null;
  for (const { enter, b } of candidates) {
    if (enter > best) break;
    const p = b.positions, n = b.normals;
    for (let i = 0; i < 3 * b.count; i += 3) {
      const nx = n[i], ny = n[i + 1], nz = n[i + 2];
      const facing = dx * nx + dy * ny + dz * nz;
      if (facing > -1e-3) continue; // back faces and edge-on discs are not drawn either
      const t = ((p[i] - ox) * nx + (p[i + 1] - oy) * ny + (p[i + 2] - oz) * nz) / facing;
      if (t < 0 || t >= best) continue;
      const ex = ox + t * dx - p[i], ey = oy + t * dy - p[i + 1], ez = oz + t * dz - p[i + 2];
      if (ex * ex + ey * ey + ez * ez > r2) continue;
      best = t;
      bestIndex = i;
      bestBrick = b;
    }
  }
  if (!bestBrick) return null;
  const n = bestBrick.normals, c = bestBrick.colors;
  const k = (bestIndex / 3) * 4;
  return {
    t: best,
    point: [ox + best * dx, oy + best * dy, oz + best * dz],
    normal: [n[bestIndex], n[bestIndex + 1], n[bestIndex + 2]],
    color: c ? [c[k], c[k + 1], c[k + 2]] : null,
  };
}

// The ray parameter where it enters brick `brick`'s reach grown by `pad` (0 when it starts
// inside), or null when it misses it or the box lies behind the origin. `inv` holds the
// reciprocal direction components (+-Infinity for an axis the ray is parallel to).
function enterBrick(origin, inv, brick, pad) {
  let t0 = 0, t1 = Infinity;
  for (let k = 0; k < 3; ++k) {
    const lo = BRICK * brick[k] + REACH_LO - pad;
    const hi = BRICK * brick[k] + REACH_HI + pad;
    if (!Number.isFinite(inv[k])) {
      if (origin[k] < lo || origin[k] > hi) return null;
      continue;
    }
    const a = (lo - origin[k]) * inv[k];
    const b = (hi - origin[k]) * inv[k];
    t0 = Math.max(t0, Math.min(a, b));
    t1 = Math.min(t1, Math.max(a, b));
  }
  return t0 <= t1 ? t0 : null;
}
