// The per-ray half of the ray caster (raycast.cpp states how a frame is traced, raycast.hpp the
// conventions): the float vector the kernel computes in, the tracing constants, and RayKernel,
// which clips, skips, samples and refines one ray and gives a hit's normal and occlusion. Only
// raycast.cpp includes it: a header, not a source file, because the frame's tile loop inlines
// every one of these calls (a call per sample across files would cost more than the sample).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "raycast.hpp"
#include "stencil.hpp"

namespace marzipan::raycasting {

constexpr float kMinStep = 0.3f;
constexpr float kJumpNudge = 1e-3f;
constexpr int kConeSteps = 64;
constexpr float kConeSlack = 1e-3f;  // relative and absolute (vu) margin on the cone's radius
constexpr int kRefineIterations = 24;
constexpr float kRefineTolerance = 1e-3f;  // |d| at which the root is taken, vu
constexpr float kInf = std::numeric_limits<float>::infinity();

struct F3 {
  float x = 0, y = 0, z = 0;
  float operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  friend F3 operator+(F3 a, F3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend F3 operator-(F3 a, F3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend F3 operator*(F3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
};
inline float dot(F3 a, F3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline F3 normalizedF(F3 a) {
  const float l = std::sqrt(dot(a, a));
  return l > 0 ? a * (1.0f / l) : F3{};
}
inline F3 toF3(Vec3 v) { return {float(v.x), float(v.y), float(v.z)}; }

// Everything one ray needs, as raw pointers and floats: built once per frame, shared read-only.
struct RayKernel {
  // The accelerator's tables, each pointing at the slot of brick (0, 0, 0): brick b (from -1, the
  // ring) is at b.x + sy * b.y + sz * b.z.
  const float* const* bricks;
  const RaycastAccel::BrickInfo* info;
  int sy, sz;
  float band;
  F3 clipLo, clipHi;
  F3 tableLo, tableHi;  // the brick table's extent, its ring included, vu

  explicit RayKernel(const RaycastAccel& a)
      : bricks(a.bricks_.data() + a.bricks_.index({0, 0, 0})),
        info(a.info_.data() + a.info_.index({0, 0, 0})),
        sy(int(a.bricks_.strideY())),
        sz(int(a.bricks_.strideZ())),
        band(a.volume_.band()),
        clipLo{-1, -1, -1},
        clipHi{float(a.volume_.dims().x), float(a.volume_.dims().y), float(a.volume_.dims().z)},
        tableLo{-kBrickSide, -kBrickSide, -kBrickSide},
        tableHi{float(Bricks::origin(a.bricks_.grid()).x + kBrickSide),
                float(Bricks::origin(a.bricks_.grid()).y + kBrickSide),
                float(Bricks::origin(a.bricks_.grid()).z + kBrickSide)} {}

  // floor for the coordinates the kernel reads, all above -kBrickSide (where the ring starts): one
  // truncation instead of the longer sequence std::floor compiles to without SSE4.1.
  static int floorIndex(float x) { return int(x + float(kBrickSide)) - kBrickSide; }

  int brickIndex(Int3 b) const { return b.x + sy * b.y + sz * b.z; }

  float voxel(Int3 p) const { return bricks[brickIndex(Bricks::brickOf(p))][Bricks::indexOf(p)]; }

  // The 8 corners of the cell holding p (index dx + 2*dy + 4*dz) and p's offset in the cell.
  void cell(F3 p, float c[8], float f[3]) const {
    const Int3 i{floorIndex(p.x), floorIndex(p.y), floorIndex(p.z)};
    f[0] = p.x - float(i.x), f[1] = p.y - float(i.y), f[2] = p.z - float(i.z);
    const Int3 l = Bricks::localOf(i);
    if (l.x != Bricks::kMask && l.y != Bricks::kMask && l.z != Bricks::kMask) {
      constexpr int kY = Bricks::index(0, 1, 0), kZ = Bricks::index(0, 0, 1);
      const float* v = bricks[brickIndex(Bricks::brickOf(i))] + Bricks::index(l);
      c[0] = v[0], c[1] = v[1], c[2] = v[kY], c[3] = v[kY + 1];
      c[4] = v[kZ], c[5] = v[kZ + 1], c[6] = v[kZ + kY], c[7] = v[kZ + kY + 1];
      return;
    }
    // The cell crosses into the next brick along some axes: per axis, the step to the upper
    // corner in the brick table and in a brick's floats.
    constexpr int kLocal[3] = {Bricks::index(1, 0, 0), Bricks::index(0, 1, 0), Bricks::index(0, 0, 1)};
    const int table[3] = {1, sy, sz};
    int db[3], dl[3];
    for (int a = 0; a < 3; ++a) {
      const bool cross = l[a] == Bricks::kMask;
      db[a] = cross ? table[a] : 0;
      dl[a] = cross ? -Bricks::kMask * kLocal[a] : kLocal[a];
    }
    const float* const* b = bricks + brickIndex(Bricks::brickOf(i));
    const int li = Bricks::index(l);
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx)
          c[dx + 2 * dy + 4 * dz] = b[dx * db[0] + dy * db[1] + dz * db[2]][li + dx * dl[0] + dy * dl[1] + dz * dl[2]];
  }

  float sample(F3 p) const {
    float c[8], f[3];
    cell(p, c, f);
    const float x00 = c[0] + f[0] * (c[1] - c[0]), x10 = c[2] + f[0] * (c[3] - c[2]);
    const float x01 = c[4] + f[0] * (c[5] - c[4]), x11 = c[6] + f[0] * (c[7] - c[6]);
    const float y0 = x00 + f[1] * (x10 - x00), y1 = x01 + f[1] * (x11 - x01);
    return y0 + f[2] * (y1 - y0);
  }

  // The analytic gradient of the trilinear interpolant.
  F3 gradient(F3 p) const {
    float c[8], f[3];
    cell(p, c, f);
    const float gx = f[0], gy = f[1], gz = f[2], hx = 1 - gx, hy = 1 - gy, hz = 1 - gz;
    return {hy * hz * (c[1] - c[0]) + gy * hz * (c[3] - c[2]) + hy * gz * (c[5] - c[4]) + gy * gz * (c[7] - c[6]),
            hx * hz * (c[2] - c[0]) + gx * hz * (c[3] - c[1]) + hx * gz * (c[6] - c[4]) + gx * gz * (c[7] - c[5]),
            hx * hy * (c[4] - c[0]) + gx * hy * (c[5] - c[1]) + hx * gy * (c[6] - c[2]) + gx * gy * (c[7] - c[3])};
  }

  // The brick holding p (coordinates from -1) and its entry in the table.
  const RaycastAccel::BrickInfo& brickAt(F3 p, int b[3]) const {
    b[0] = Bricks::brickOf(floorIndex(p.x)), b[1] = Bricks::brickOf(floorIndex(p.y)), b[2] = Bricks::brickOf(floorIndex(p.z));
    return info[brickIndex({b[0], b[1], b[2]})];
  }

  // How far along the unit axis a, from o, a cone of half-angle atan(tanA) holds no zero of the
  // interpolant: every ray inside the cone may start there. Cone marching: a ball of radius e
  // around the axis point q known to be empty lets the axis advance while the cone's
  // cross-section (radius t*tanA) stays in the ball.
  float coneStart(F3 o, F3 a, float tanA) const {
    float t = 0;
    for (int i = 0; i < kConeSteps; ++i) {
      const float rho = t * tanA * (1 + kConeSlack) + kConeSlack;
      const float e = emptyRadius(o + a * t);
      if (e <= rho) break;
      t += (e - rho) / (1 + tanA);
    }
    return t;
  }

  // The radius of a ball around q that holds no cell that may hold a zero (0 if q is in one).
  float emptyRadius(F3 q) const {
    bool inTable = true;
    for (int k = 0; k < 3; ++k) inTable = inTable && q[k] >= tableLo[k] && q[k] < tableHi[k];
    float e = 0;
    if (inTable) {
      int b[3];
      const int r = brickAt(q, b).reach;
      if (r == 0) return 0;
      // The cube of bricks [b - r + 1, b + r - 1] holds no such cell.
      e = kInf;
      for (int k = 0; k < 3; ++k)
        e = std::min({e, q[k] - float(kBrickSide * (b[k] - r + 1)), float(kBrickSide * (b[k] + r)) - q[k]});
    } else {
      // Far outside the domain: the slab beyond the clip box along some axis is empty.
      for (int k = 0; k < 3; ++k) e = std::max({e, clipLo[k] - q[k], q[k] - clipHi[k]});
    }
    return e;
  }

  // The reverse: from which axis parameter on the cone holds no such zero, marching back from
  // beyond the far corner of the clip box.
  float coneEnd(F3 o, F3 a, float tanA) const {
    float far = 0;
    for (int k = 0; k < 3; ++k) {
      const float span = std::max(std::fabs(clipLo[k] - o[k]), std::fabs(clipHi[k] - o[k]));
      far += span * span;
    }
    float t = std::sqrt(far) + 1;
    for (int i = 0; i < kConeSteps && t > 0; ++i) {
      const float rho = t * tanA * (1 + kConeSlack) + kConeSlack;
      const float e = emptyRadius(o + a * t);
      if (e <= rho) return t;
      // Going back the cross-section shrinks: the ball at t holds every cross-section down to t - (e - rho).
      t -= e - rho;
    }
    return std::max(t, 0.0f);
  }

  // One ray in flight. Rays advance one step at a time so that several independent rays can be
  // interleaved: each step is a chain of dependent loads and arithmetic, and interleaving lets
  // the processor overlap the chains of different rays.
  struct Ray {
    F3 o, d;
    float inv[3];
    float t, t1;
    float tPrev, dPrev;  // the last point known to be outside the solid; d there, or -1 if unsampled
    bool outside;        // false until some point of the ray is known to be outside the solid
    bool done;
    float hit;  // distance to the first zero of the interpolant, +inf for none
    int octant;    // bit a set when d[a] < 0
    float tLeave;  // where the ray leaves the cells that may hold a zero it samples in
    float faceBase[3], faceStep[3];  // kBrickSide, -kBrickSide going down along an axis; 0, kBrickSide up
  };

  // Starts a ray from o along the unit direction d that is known to meet no zero before tSafe
  // nor after tEnd (from the tile's cone).
  void start(Ray& r, F3 o, F3 d, float tSafe, float tEnd) const {
    r.o = o, r.d = d, r.done = true, r.hit = kInf;
    r.tLeave = -kInf;
    r.octant = (d.x < 0 ? 1 : 0) | (d.y < 0 ? 2 : 0) | (d.z < 0 ? 4 : 0);
    for (int a = 0; a < 3; ++a) {
      r.faceBase[a] = d[a] < 0 ? float(kBrickSide) : 0.0f;
      r.faceStep[a] = d[a] < 0 ? -float(kBrickSide) : float(kBrickSide);
    }
    float t0 = 0, t1 = tEnd;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0) {
        r.inv[a] = kInf;
        if (o[a] < clipLo[a] || o[a] > clipHi[a]) return;
        continue;
      }
      r.inv[a] = 1.0f / d[a];
      float ta = (clipLo[a] - o[a]) * r.inv[a], tb = (clipHi[a] - o[a]) * r.inv[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    // On the clip box the field is +band: only an eye inside the box may start inside the solid.
    r.t = std::max(t0, tSafe), r.t1 = t1, r.tPrev = r.t, r.dPrev = -1, r.outside = r.t > 0;
    r.done = !(r.t <= r.t1);
  }


  // Places a ray that has left the last cells it sampled in: a jump over empty space (false), or
  // onto the next point of cells that may hold a zero (true, p updated, tLeave where the ray
  // leaves them).
  bool findCells(Ray& r, F3& p) const {
    int b[3];
    const RaycastAccel::BrickInfo& in = brickAt(p, b);
    // The bricks from b to b + reach - 1 along the ray's octant hold no cell that may hold a zero.
    int reach = in.octant[r.octant];
    if (reach == 0) {
      // Outside the brick's cells that may hold a zero the interpolant is positive: go to where
      // the ray enters them, or leave the brick. An axis the ray does not move along has
      // inv = +inf: a box beside the ray gives an entry of +inf or an exit of -inf, and a face
      // the ray lies in gives NaN, which max and min ignore.
      float enter = -kInf, leave = kInf;
      for (int a = 0; a < 3; ++a) {
        const float lo = float(kBrickSide * b[a] + in.lo[a]), hi = float(kBrickSide * b[a] + in.hi[a] + 1);
        const bool down = r.octant & (1 << a);
        enter = std::max(enter, ((down ? hi : lo) - r.o[a]) * r.inv[a]);
        leave = std::min(leave, ((down ? lo : hi) - r.o[a]) * r.inv[a]);
      }
      if (enter <= leave && leave >= r.t) {
        r.tLeave = leave;
        if (enter > r.t) {
          r.t = enter, r.tPrev = enter, r.dPrev = -1, r.outside = true;
          if (r.t > r.t1) {
            r.done = true;
            return false;
          }
          p = r.o + r.d * r.t;
        }
        return true;
      }
      reach = 1;
    }
    // Where the ray leaves those bricks: per axis, the face ahead, (b + reach) * kBrickSide going
    // up and (b + 1 - reach) * kBrickSide going down. An axis the ray does not move along has
    // inv = +inf and a face ahead of it, so it never decides.
    float exit = kInf;
    for (int a = 0; a < 3; ++a) {
      const float face = float(kBrickSide * b[a]) + r.faceBase[a] + r.faceStep[a] * float(reach);
      exit = std::min(exit, (face - r.o[a]) * r.inv[a]);
    }
    r.tPrev = std::max(r.t, exit), r.dPrev = -1, r.outside = true;
    // The value at the exit is positive but unknown: sample next just past it. The nudge stays
    // several float steps above t, so the ray always moves on.
    r.t = r.tPrev + kJumpNudge + r.tPrev * 1e-6f;
    r.done = r.t > r.t1;
    return false;
  }

  // One jump or one sample.
  void step(Ray& r) const {
    F3 p = r.o + r.d * r.t;
    if (!(r.t <= r.tLeave) && !findCells(r, p)) return;
    const float dist = sample(p);
    if (dist <= 0) {
      r.done = true;
      if (!r.outside) {
        r.hit = r.t;
        return;
      }
      if (r.dPrev < 0) r.dPrev = sample(r.o + r.d * r.tPrev);
      r.hit = r.dPrev > 0 ? refine(r.o, r.d, r.tPrev, r.dPrev, r.t, dist) : r.tPrev;
      return;
    }
    r.outside = true;
    r.tPrev = r.t, r.dPrev = dist;
    r.t += std::max(dist, kMinStep);
    r.done = r.t > r.t1;
  }

  // Runs n rays to completion, a step of each in turn.
  void trace(Ray* rays, int n) const {
    for (bool busy = true; busy;) {
      busy = false;
      for (int i = 0; i < n; ++i)
        if (!rays[i].done) {
          step(rays[i]);
          busy = true;
        }
    }
  }

  // Illinois regula falsi on [a, b] where the interpolant goes from fa > 0 to fb <= 0.
  float refine(F3 o, F3 d, float a, float fa, float b, float fb) const {
    int kept = 0;  // which end the last two steps kept: -1 a, +1 b
    for (int i = 0; i < kRefineIterations; ++i) {
      const float m = (a * fb - b * fa) / (fb - fa);
      const float fm = sample(o + d * m);
      if (std::fabs(fm) < kRefineTolerance) return m;
      if (fm > 0) {
        a = m, fa = fm;
        if (kept == -1) fb *= 0.5f;
        kept = -1;
      } else {
        b = m, fb = fm;
        if (kept == 1) fa *= 0.5f;
        kept = 1;
      }
    }
    return (a * fb - b * fa) / (fb - fa);
  }

  // Largest | |grad d| - 1 | over the 8 corners of the cell holding p (central differences).
  float gradientError(F3 p) const {
    const Int3 i{floorIndex(p.x), floorIndex(p.y), floorIndex(p.z)};
    float worst = 0;
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          float g[3];
          GradStencil::around(i + Int3{dx, dy, dz}, [&](Int3 q) { return voxel(q); }).gradient(g);
          worst = std::max(worst, std::fabs(std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) - 1));
        }
    return worst;
  }

  // A smooth normal field: the central-difference gradients at the 8 corners of the cell holding
  // p, blended trilinearly. The analytic gradient of the trilinear interpolant (gradient())
  // jumps across cell faces, which draws the voxel grid as contour steps on smooth surfaces;
  // this one is continuous, so shading varies smoothly across cells.
  F3 smoothGradient(F3 p) const {
    const Int3 i{floorIndex(p.x), floorIndex(p.y), floorIndex(p.z)};
    const float f[3] = {p.x - float(i.x), p.y - float(i.y), p.z - float(i.z)};
    // The 4x4x4 voxels around the cell, read once.
    float v[4][4][4];
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) v[z][y][x] = voxel(i + Int3{x - 1, y - 1, z - 1});
    F3 g{};
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const float w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
          const GradStencil s = GradStencil::inArray(&v[dz + 1][dy + 1][dx + 1], 1, 4, 16);
          g = g + F3{s.difference(0), s.difference(1), s.difference(2)} * (0.5f * w);
        }
    return g;
  }

  // Ambient occlusion from the field itself: along the normal, an unoccluded surface has d equal
  // to the offset; the relative shortfall measures nearby material. Offsets stay inside the band
  // (beyond it d is clamped) and catch creases and contact shadows at a few voxels' scale.
  // Interactive frames take two samples; stills take five, spread over the band and weighted
  // towards the surface, which makes the darkening of a crease fade out gradually (soft).
  float occlusion(F3 p, F3 n, bool still) const {
    if (!still) {
      const float s1 = band * 0.35f, s2 = band * 0.7f;
      const float occ = 0.6f * std::max(0.0f, s1 - sample(p + n * s1)) / s1 +
                        0.4f * std::max(0.0f, s2 - sample(p + n * s2)) / s2;
      return std::clamp(1.0f - 1.2f * occ, 0.0f, 1.0f);
    }
    constexpr int kSamples = 5;
    float occ = 0, weights = 0;
    for (int i = 1; i <= kSamples; ++i) {
      const float s = band * 0.9f * float(i) / kSamples;
      const float w = 1.0f / float(i);
      occ += w * std::max(0.0f, s - sample(p + n * s)) / s;
      weights += w;
    }
    return std::clamp(1.0f - 1.2f * occ / weights, 0.0f, 1.0f);
  }
};

}  // namespace marzipan::raycasting
