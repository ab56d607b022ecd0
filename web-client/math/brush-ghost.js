// What the brush cursor draws for a tool at a surface point, as plain geometry: rings (circles
// given by centre, normal and radius) and straight segments. Brushes get the ring of their
// radius in the surface's tangent plane and an inner ring at radius × strength (the strongest
// part of the window, and how strong); CSG tools get a ghost of the shape they apply, centred
// on the point as the server centres it (PROTOCOL.md: sphere radius, box half side, cylinder
// radius and half height, axis-aligned).
// Conventions: vu, world axes; a ring's normal is unit.

const AXES = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

// kind: "stroke" or "click"; shape: sphere|box|cylinder (click tools); axis: 0, 1, 2 (cylinder).
// Returns {rings: [{center, normal, radius, inner}], segments: [[a, b]]}.
export function brushGhost({ kind, shape = "sphere", axis = 1, strength = 1 }, center, normal, radius) {
  if (kind === "stroke") {
    const rings = [{ center, normal, radius, inner: false }];
    if (strength < 1) rings.push({ center, normal, radius: radius * strength, inner: true });
    return { rings, segments: [] };
  }
  if (shape === "sphere") return { rings: AXES.map((n) => ({ center, normal: n, radius, inner: false })), segments: [] };
  if (shape === "cylinder") {
    const a = AXES[axis];
    const end = (s) => center.map((c, i) => c + s * radius * a[i]);
    const rings = [-1, 1].map((s) => ({ center: end(s), normal: a, radius, inner: false }));
    const [u, v] = AXES.filter((_, i) => i !== axis);
    const segments = [];
    for (const [d, sign] of [[u, 1], [u, -1], [v, 1], [v, -1]]) {
      const off = d.map((x) => x * sign * radius);
      segments.push([end(-1).map((c, i) => c + off[i]), end(1).map((c, i) => c + off[i])]);
    }
    return { rings, segments };
  }
  // box: its 12 edges
  const corner = (sx, sy, sz) => [center[0] + sx * radius, center[1] + sy * radius, center[2] + sz * radius];
  const segments = [];
  for (const a of [-1, 1])
    for (const b of [-1, 1]) {
      segments.push([corner(-1, a, b), corner(1, a, b)]);
      segments.push([corner(a, -1, b), corner(a, 1, b)]);
      segments.push([corner(a, b, -1), corner(a, b, 1)]);
    }
  return { rings: [], segments };
}
