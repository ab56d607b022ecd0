// Ray casting by sphere tracing with empty-space skipping (conventions in raycast.hpp).
//
// Per 16x16 tile, a cone holding all the tile's rays is marched once through the brick level
// (RaycastAccel) from the eye and once back from beyond the domain: every ray of the tile starts
// where the cone first nears a brick with cells that may hold a zero, and stops where it last
// leaves one. Each ray is clipped to the box [-1, dims] (beyond it the field is +band), then:
// - in a brick with no such cell, it jumps to the exit of the box of such bricks ahead of it in
//   its octant of directions (reach per octant); in a brick with some, it jumps to where it
//   enters their box, or leaves the brick, and samples until it leaves that box;
// - elsewhere it samples the trilinear interpolant d and steps by max(d, kMinStep): d underestimates
//   the distance to the surface in the clamped part of the band, and near the surface the floor
//   makes the ray cross the zero set in a few steps instead of creeping towards it;
// - a sign change between two samples is refined by Illinois regula falsi on the interpolant.
// A cell with every corner > 0 has a positive interpolant, so no skip can pass over a zero.
// Rays of a row advance in groups of kGroup, one step each in turn: a step is a chain of
// dependent loads and arithmetic, and interleaving independent rays overlaps those chains.
// Sampling reads one brick pointer for the 8 corners when the cell lies inside one brick (7 cells
// in 8 per axis) and the flat, padded brick table otherwise; uniform bricks point at constant
// bricks, so there is no branch on brick kind. The kernel works in float: depths up to a few
// thousand vu keep ~1e-3 vu of precision or better, below the interpolant's own error.
// A preview traces one pixel in four (even x and y) and blends or traces the others in a second
// pass (render, where its rules and its one approximation are stated).
#include "raycast.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <sstream>

#include "color_space.hpp"
#include "errors.hpp"
#include "stencil.hpp"
#include "thickness.hpp"

namespace marzipan {

namespace {

constexpr int kTile = 16;  // even: a tile holds whole 2x2 blocks of a preview
constexpr int kGroup = 4;  // rays traced together, interleaved
constexpr float kMinStep = 0.3f;
constexpr float kJumpNudge = 1e-3f;
constexpr int kConeSteps = 64;
constexpr float kConeSlack = 1e-3f;  // relative and absolute (vu) margin on the cone's radius
constexpr int kRefineIterations = 24;
constexpr float kRefineTolerance = 1e-3f;  // |d| at which the root is taken, vu
// Preview frames (pass 2 in render): what lets a pixel be blended from its lattice neighbours.
// 8 vu rather than 2: a surface turning away near a silhouette is blended too (0.92 vu of depth
// error at most on the benchmark's sphere, no visible change), 19% fewer instructions there.
constexpr float kPreviewDepthJump = 8.0f;  // vu between the nearest and farthest neighbour hit
constexpr float kPreviewCosine = 0.97f;    // between their normals (about 14 degrees)
constexpr int kPreviewContrast = 12;       // per output channel, 0-255
constexpr float kGradientErrorWhite = 0.1f;
constexpr float kInf = std::numeric_limits<float>::infinity();

struct F3 {
  float x = 0, y = 0, z = 0;
  float operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  friend F3 operator+(F3 a, F3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend F3 operator-(F3 a, F3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend F3 operator*(F3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
};
float dot(F3 a, F3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
F3 normalizedF(F3 a) {
  const float l = std::sqrt(dot(a, a));
  return l > 0 ? a * (1.0f / l) : F3{};
}
F3 toF3(Vec3 v) { return {float(v.x), float(v.y), float(v.z)}; }

// Linear [0, 1] to 8-bit sRGB through a table: the exact curve per pixel would cost more than
// the rest of the shading.
const std::array<std::uint8_t, 4097>& srgbTable() {
  static const std::array<std::uint8_t, 4097> table = [] {
    std::array<std::uint8_t, 4097> t{};
    for (int i = 0; i <= 4096; ++i) {
      const double c = i / 4096.0;
      const double s = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055;
      t[i] = std::uint8_t(std::lround(std::clamp(s, 0.0, 1.0) * 255));
    }
    return t;
  }();
  return table;
}

// The albedo of each texel colour byte (color_space.hpp), looked up per corner of a hit's cell.
const std::array<float, 256>& linearTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = srgbToLinear(std::uint8_t(i));
    return t;
  }();
  return table;
}

std::uint8_t toByte(float linear, const std::array<std::uint8_t, 4097>& table) {
  return table[int(std::clamp(linear, 0.0f, 1.0f) * 4096.0f + 0.5f)];
}

// The camera's orthonormal frame: forward, right, upward on screen.
struct View {
  F3 eye, forward, right, up;
  F3 light;  // towards the key light: from the camera's upper left
  float tanHalf, aspect, width, height;

  // The unit ray through the centre of pixel (x, y); fractional pixels interpolate.
  F3 ray(float x, float y) const {
    const float sx = (2.0f * (x + 0.5f) / width - 1.0f) * tanHalf * aspect;
    const float sy = (1.0f - 2.0f * (y + 0.5f) / height) * tanHalf;
    return normalizedF(forward + right * sx + up * sy);
  }
};

View makeView(const Camera& c) {
  const Vec3 f = normalized(c.target - c.eye);
  const Vec3 r = normalized(cross(f, c.up));
  const Vec3 u = cross(r, f);
  constexpr double kPi = 3.14159265358979323846;
  return {toF3(c.eye),
          toF3(f),
          toF3(r),
          toF3(u),
          toF3(normalized(r * -0.45 + u * 0.65 - f * 0.6)),
          float(std::tan(c.fovY_degrees * kPi / 360.0)),
          float(c.width) / float(c.height),
          float(c.width),
          float(c.height)};
}

}  // namespace

RaycastAccel::RaycastAccel(const Volume& volume, ThreadPool& pool) : volume_(volume) {
  const Int3 bd = volume_.brickDims();
  const Int3 dims = volume_.dims();
  const float w = volume_.band();

  auto outside = std::make_shared<Brick>();
  auto inside = std::make_shared<Brick>();
  std::fill(std::begin(outside->v), std::end(outside->v), w);
  std::fill(std::begin(inside->v), std::end(inside->v), -w);
  owned_ = {outside, inside};
  bricks_ = BrickGrid<const float*>(bd, 1, outside->v);

  for (int bz = 0; bz < bd.z; ++bz)
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const Int3 b{bx, by, bz};
        float u;
        const float* data = volume_.brickData(b, &u);
        if (data) {
          bricks_[b] = data;
          continue;
        }
        if (u > 0) continue;
        const Box voxels = Bricks::box(b);
        if (voxels.hi.x <= dims.x && voxels.hi.y <= dims.y && voxels.hi.z <= dims.z) {
          bricks_[b] = inside->v;
          continue;
        }
        // A partial brick at the domain's far edge: its voxels past the edge read +band.
        auto edge = std::make_shared<Brick>();
        for (int k = 0; k < kBrickVoxels; ++k) {
          const Int3 p = voxels.lo + Bricks::local(k);
          edge->v[k] = p.x < dims.x && p.y < dims.y && p.z < dims.z ? -w : w;
        }
        bricks_[b] = edge->v;
        owned_.push_back(std::move(edge));
      }

  // The box of each brick's voxels <= 0, local coordinates (none when lo > hi).
  struct VoxelBox {
    std::int8_t lo[3] = {kBrickSide, kBrickSide, kBrickSide}, hi[3] = {-1, -1, -1};
  };
  BrickGrid<VoxelBox> negative(bd, 0);
  pool.parallelFor(std::size_t(bd.z), [&](std::size_t bz) {
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const Int3 b{bx, by, int(bz)};
        const float* v = bricks_[b];
        VoxelBox& box = negative[b];
        if (v == outside->v) continue;
        if (v == inside->v) {
          box = {{0, 0, 0}, {Bricks::kMask, Bricks::kMask, Bricks::kMask}};
          continue;
        }
        int nonPositive = 0;  // a vectorizable first look: most stored bricks have none
        for (int k = 0; k < kBrickVoxels; ++k) nonPositive += v[k] <= 0 ? 1 : 0;
        if (!nonPositive) continue;
        int rows = 0, minX = kBrickSide, maxX = -1;
        for (int z = 0; z < kBrickSide; ++z)
          for (int y = 0; y < kBrickSide; ++y) {
            const float* row = v + Bricks::index(0, y, z);
            unsigned mask = 0;
            for (int x = 0; x < kBrickSide; ++x) mask |= unsigned(row[x] <= 0) << x;
            if (!mask) continue;
            ++rows;
            minX = std::min(minX, std::countr_zero(mask));
            maxX = std::max(maxX, 31 - std::countl_zero(mask));
            box.lo[1] = std::int8_t(std::min<int>(box.lo[1], y)), box.hi[1] = std::int8_t(std::max<int>(box.hi[1], y));
            box.lo[2] = std::int8_t(std::min<int>(box.lo[2], z)), box.hi[2] = std::int8_t(std::max<int>(box.hi[2], z));
          }
        if (rows) box.lo[0] = std::int8_t(minX), box.hi[0] = std::int8_t(maxX);
      }
  });

  // A voxel <= 0 puts a possible zero in the 8 cells it is a corner of, so a brick's box grows
  // by one cell downwards, into the bricks below it along each axis.
  info_ = BrickGrid<BrickInfo>(bd, 1, BrickInfo{255, {}, {kBrickSide, kBrickSide, kBrickSide}, {0, 0, 0}});
  for (int bz = 0; bz < bd.z; ++bz)
    for (int by = 0; by < bd.y; ++by)
      for (int bx = 0; bx < bd.x; ++bx) {
        const VoxelBox& box = negative[Int3{bx, by, bz}];
        if (box.lo[0] > box.hi[0]) continue;
        const Int3 o = Bricks::origin({bx, by, bz});
        int cellLo[3], cellHi[3];
        for (int k = 0; k < 3; ++k) cellLo[k] = o[k] + box.lo[k] - 1, cellHi[k] = o[k] + box.hi[k];
        for (int dz = -1; dz <= 0; ++dz)
          for (int dy = -1; dy <= 0; ++dy)
            for (int dx = -1; dx <= 0; ++dx) {
              const Int3 nb{bx + dx, by + dy, bz + dz};
              const Int3 no = Bricks::origin(nb);
              int lo[3], hi[3];
              bool any = true;
              for (int k = 0; k < 3; ++k) {
                lo[k] = std::max(cellLo[k], no[k]) - no[k];
                hi[k] = std::min(cellHi[k], no[k] + Bricks::kMask) - no[k];
                any = any && lo[k] <= hi[k];
              }
              if (!any) continue;
              BrickInfo& info = info_[nb];
              info.reach = 0;
              for (int k = 0; k < 3; ++k) {
                info.lo[k] = std::uint8_t(std::min<int>(info.lo[k], lo[k]));
                info.hi[k] = std::uint8_t(std::max<int>(info.hi[k], hi[k]));
              }
            }
      }

  // Per octant of ray directions, the chessboard distance in bricks to the nearest brick with
  // such cells among those a ray of the octant can still enter (none at a lower index along an
  // axis it goes up, none at a higher one along an axis it goes down): a forward chessboard
  // transform, one raster pass against the octant, exact because every brick of that region is
  // reached by king moves into it. Per brick, a pass takes the 7 neighbours into the octant: 2
  // in each of the 3 rows already done (gathered a row at a time), then the row's previous
  // brick, the only sequential dependency. The plain distance, for the tile cones, is the
  // smallest of the 8.
  const Int3 p = bd + Int3{2, 2, 2};  // the table, its ring included
  const std::size_t n = info_.size(), sy = info_.strideY(), sz = info_.strideZ();
  std::vector<std::uint8_t> seed(n), reach(n);
  for (std::size_t i = 0; i < n; ++i) seed[i] = info_[i].reach;
  std::vector<std::uint8_t> near(std::size_t(p.x));
  for (int octant = 0; octant < 8; ++octant) {
    const int s[3] = {octant & 1 ? -1 : 1, octant & 2 ? -1 : 1, octant & 4 ? -1 : 1};
    // The x range where the neighbour x + s[0] is in the table too; the other end brick has only x.
    const int xLo = s[0] > 0 ? 0 : 1, xHi = s[0] > 0 ? p.x - 1 : p.x, xEdge = s[0] > 0 ? p.x - 1 : 0;
    for (int zi = 0; zi < p.z; ++zi) {
      const int z = s[2] > 0 ? p.z - 1 - zi : zi, zn = z + s[2];
      for (int yi = 0; yi < p.y; ++yi) {
        const int y = s[1] > 0 ? p.y - 1 - yi : yi, yn = y + s[1];
        std::fill(near.begin(), near.end(), std::uint8_t(255));
        for (const auto& [ry, rz] : {std::pair{yn, z}, std::pair{y, zn}, std::pair{yn, zn}}) {
          if (ry < 0 || ry >= p.y || rz < 0 || rz >= p.z) continue;
          const std::uint8_t* row = &reach[sy * std::size_t(ry) + sz * std::size_t(rz)];
          std::uint8_t* out = near.data();
          for (int x = xLo; x < xHi; ++x)
            out[x] = std::min<std::uint8_t>(out[x], std::min<std::uint8_t>(std::min(row[x], row[x + s[0]]), 254) + 1);
          out[xEdge] = std::min<std::uint8_t>(out[xEdge], std::min<std::uint8_t>(row[xEdge], 254) + 1);
        }
        const std::size_t base = sy * std::size_t(y) + sz * std::size_t(z);
        int prev = 255;
        for (int xi = 0; xi < p.x; ++xi) {
          const int x = s[0] > 0 ? p.x - 1 - xi : xi;
          prev = seed[base + x] ? std::min({int(near[std::size_t(x)]), prev + 1, 255}) : 0;
          reach[base + x] = std::uint8_t(prev);
        }
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      info_[i].octant[octant] = reach[i];
      info_[i].reach = octant ? std::min(info_[i].reach, reach[i]) : reach[i];
    }
  }
}

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

namespace {

struct Background {
  float top[3] = {0.070f, 0.078f, 0.095f};
  float bottom[3] = {0.018f, 0.020f, 0.024f};
};

// How much darker fully masked clay is drawn (weight 255: its albedo times 1 - this), as the
// web client draws it (web-client/render/gl-program.js).
constexpr float kMaskDarkening = 0.45f;

// Clay lit from the camera's upper left, with a cool sky / warm ground hemisphere fill. The
// albedo is kClayColor's (channels.hpp) in linear light; painted surfaces take their texels'.
struct Material {
  F3 albedo{0.72f, 0.46f, 0.33f};
  F3 key{1.10f, 1.03f, 0.94f};
  F3 sky{0.26f, 0.29f, 0.36f};
  F3 ground{0.12f, 0.09f, 0.07f};
  float wrap = 0.2f;
  float specular = 0.10f;
};

F3 shadeLit(const RayKernel& k, const View& v, const Material& m, F3 p, F3 n, F3 dir, bool still) {
  const F3 toEye = dir * -1.0f;
  const F3 light = v.light;
  const float ao = k.occlusion(p, n, still);
  const float diffuse = std::max(0.0f, (dot(n, light) + m.wrap) / (1 + m.wrap));
  const float h = 0.5f + 0.5f * dot(n, v.up);
  const F3 half = normalizedF(light + toEye);
  float s = std::max(0.0f, dot(n, half));
  s *= s, s *= s, s *= s, s *= s, s *= s;  // ^32: clay is rough, the highlight is broad and faint
  const float spec = dot(n, light) > 0 ? m.specular * s : 0.0f;
  const float keyShade = diffuse * (0.55f + 0.45f * ao);
  const F3 fill = m.ground + (m.sky - m.ground) * h;
  return {m.albedo.x * (m.key.x * keyShade + fill.x * ao) + m.key.x * spec,
          m.albedo.y * (m.key.y * keyShade + fill.y * ao) + m.key.y * spec,
          m.albedo.z * (m.key.z * keyShade + fill.z * ao) + m.key.z * spec};
}

// A pixel's colour before output: linear light for Lit (sRGB is applied after averaging
// samples), display values in [0, 1] for Normals and GradientError.
struct Shader {
  const RayKernel& kernel;
  const View& view;
  const Material& material;
  const Background& background;
  Shading shading;
  bool still;
  float height;
  const Volume& volume;
  double thicknessMin;
  // Lit frames take the texels' colour (albedoAt) when the volume has channels or a base colour
  // other than the clay, whose albedo Material holds.
  bool coloured;

  F3 backgroundAt(float y) const {
    const float along = y / std::max(1.0f, height - 1);
    F3 c{background.top[0] + along * (background.bottom[0] - background.top[0]),
         background.top[1] + along * (background.bottom[1] - background.top[1]),
         background.top[2] + along * (background.bottom[2] - background.top[2])};
    if (shading == Shading::Lit || shading == Shading::Thickness) return c;
    for (float* ch : {&c.x, &c.y, &c.z}) *ch = float(srgbTable()[int(std::clamp(*ch, 0.0f, 1.0f) * 4096.0f + 0.5f)]) / 255.0f;
    return c;
  }

  // The albedo at surface point p of a volume with channels: the texels of the cell's eight
  // corners in linear light, blended trilinearly (colour is constant along the normals through
  // the band, paint.hpp, so the corners read the colour painted on the surface between them),
  // darkened by the mask as the web client shows it (kMaskDarkening at weight 255).
  F3 albedoAt(F3 p) const {
    const Int3 dims = volume.dims();
    const auto& lin = linearTable();
    float c[3] = {std::clamp(p.x, 0.0f, float(dims.x - 1)), std::clamp(p.y, 0.0f, float(dims.y - 1)),
                  std::clamp(p.z, 0.0f, float(dims.z - 1))};
    int lo[3];
    float f[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(int(c[a]), (a == 0 ? dims.x : a == 1 ? dims.y : dims.z) - 2);
      lo[a] = std::max(lo[a], 0);
      f[a] = std::clamp(c[a] - float(lo[a]), 0.0f, 1.0f);
    }
    F3 sum{};
    float mask = 0;
    for (int k = 0; k < 8; ++k) {
      const int dx = k & 1, dy = (k >> 1) & 1, dz = k >> 2;
      const float w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
      if (w == 0) continue;
      const Texel t = volume.texel({lo[0] + dx, lo[1] + dy, lo[2] + dz});
      sum = sum + F3{lin[t.r], lin[t.g], lin[t.b]} * w;
      mask += w * float(t.mask);
    }
    return sum * (1.0f - kMaskDarkening * mask / 255.0f);
  }

  F3 normalAt(F3 p, F3 dir) const {
    F3 n = normalizedF(still ? kernel.smoothGradient(p) : kernel.gradient(p));
    return dot(n, n) == 0 ? dir * -1.0f : n;
  }

  // The colour of the surface hit at distance t along the unit ray dir.
  // The surface normal there goes to *normal when asked for.
  F3 hit(F3 dir, float t, F3* normal = nullptr) const {
    const F3 p = view.eye + dir * t;
    if (normal) *normal = normalAt(p, dir);
    switch (shading) {
      case Shading::Lit: {
        const F3 n = normal ? *normal : normalAt(p, dir);
        if (!coloured) return shadeLit(kernel, view, material, p, n, dir, still);
        Material painted = material;
        painted.albedo = albedoAt(p);
        return shadeLit(kernel, view, painted, p, n, dir, still);
      }
      case Shading::Normals: {
        const F3 n = normal ? *normal : normalAt(p, dir);
        return {0.5f * (n.x + 1), 0.5f * (n.y + 1), 0.5f * (n.z + 1)};
      }
      case Shading::Thickness: {
        const F3 n = normal ? *normal : normalAt(p, dir);
        const double thick = thicknessAt(volume, {p.x, p.y, p.z}, {n.x, n.y, n.z});
        const F3 red{0.80f, 0.06f, 0.04f}, yellow{0.85f, 0.62f, 0.10f};
        const float s = float(std::clamp((thick - thicknessMin) / thicknessMin, 0.0, 2.0));
        Material tinted = material;
        tinted.albedo = thick < thicknessMin ? red : s < 1 ? yellow : yellow + (material.albedo - yellow) * (s - 1);
        return shadeLit(kernel, view, tinted, p, n, dir, still);
      }
      case Shading::GradientError:
        break;
    }
    const float e = std::min(1.0f, kernel.gradientError(p) / kGradientErrorWhite);
    return {e, e, e};
  }

  void store(F3 c, std::uint8_t* out, const std::array<std::uint8_t, 4097>& srgb) const {
    if (shading == Shading::Lit || shading == Shading::Thickness) {
      out[0] = toByte(c.x, srgb), out[1] = toByte(c.y, srgb), out[2] = toByte(c.z, srgb);
      return;
    }
    out[0] = std::uint8_t(std::lround(255 * std::clamp(c.x, 0.0f, 1.0f)));
    out[1] = std::uint8_t(std::lround(255 * std::clamp(c.y, 0.0f, 1.0f)));
    out[2] = std::uint8_t(std::lround(255 * std::clamp(c.z, 0.0f, 1.0f)));
  }
};

// Still frames: a pixel is an edge when a neighbour (8-connected) differs in hit or miss, lies
// at a clearly different depth (an occluding contour), or differs by more than kEdgeContrast in
// a channel (a crease); edge pixels are resolved from kAaSamples more rays on a rotated grid.
constexpr int kAaSamples = 4;
constexpr float kAaOffsets[kAaSamples][2] = {{-0.125f, -0.375f}, {0.375f, -0.125f}, {0.125f, 0.375f}, {-0.375f, 0.125f}};
constexpr int kEdgeContrast = 12;
constexpr float kEdgeDepthJump = 0.02f;  // relative to the nearer depth, plus 1 vu

bool isEdge(const Frame& f, int x, int y) {
  const std::size_t i = std::size_t(y) * f.width + x;
  const float d = f.depth[i];
  const std::uint8_t* c = &f.rgb[i * 3];
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int nx = x + dx, ny = y + dy;
      if ((!dx && !dy) || nx < 0 || ny < 0 || nx >= f.width || ny >= f.height) continue;
      const std::size_t j = std::size_t(ny) * f.width + nx;
      const float e = f.depth[j];
      if (std::isfinite(d) != std::isfinite(e)) return true;
      if (std::isfinite(d) && std::fabs(d - e) > kEdgeDepthJump * std::min(d, e) + 1) return true;
      const std::uint8_t* o = &f.rgb[j * 3];
      for (int ch = 0; ch < 3; ++ch)
        if (std::abs(int(c[ch]) - int(o[ch])) > kEdgeContrast) return true;
    }
  return false;
}

}  // namespace

Frame render(const RaycastAccel& accel, const Camera& camera, Shading shading, ThreadPool& pool, FrameQuality quality,
             double thicknessMinVu) {
  camera.validate();
  if (!(std::isfinite(thicknessMinVu) && thicknessMinVu > 0))
    throw EngineError(ErrorKind::InvalidArgument, "min_vu", "must be a finite number of vu above 0");
  const RayKernel kernel(accel);
  const View view = makeView(camera);
  const Material material;
  const Background background;
  const auto& srgb = srgbTable();
  const bool still = quality == FrameQuality::Still;
  const Volume& vol = accel.volume();
  const bool coloured = vol.paintedBricks() > 0 || !(vol.baseColor() == kClayColor);
  const Shader shader{kernel, view, material, background, shading, still, float(camera.height), vol,
                      thicknessMinVu, coloured};

  Frame frame;
  frame.width = camera.width;
  frame.height = camera.height;
  frame.rgb.assign(std::size_t(camera.width) * camera.height * 3, 0);
  frame.depth.assign(std::size_t(camera.width) * camera.height, kInf);
  const int tilesX = (camera.width + kTile - 1) / kTile, tilesY = (camera.height + kTile - 1) / kTile;
  const std::size_t tiles = std::size_t(tilesX) * tilesY;

  // Per tile, the cone around the ray through the tile's middle that holds its four corner rays,
  // marched once for all of them: where its rays may start (tSafe) and end (tEnd along the axis).
  // (Cones per 8x8 block were tried: their extra marching cost more than they saved.)
  struct Cone {
    int x0, y0, x1, y1;
    F3 axis;
    float tSafe, tEnd;
    bool empty;  // every ray of the tile ends before it starts: all background
  };
  auto coneOf = [&](std::size_t tile) {
    const int x0 = int(tile % tilesX) * kTile, y0 = int(tile / tilesX) * kTile;
    const int x1 = std::min(x0 + kTile, camera.width), y1 = std::min(y0 + kTile, camera.height);
    Cone c{x0, y0, x1, y1, view.ray(0.5f * float(x0 + x1 - 1), 0.5f * float(y0 + y1 - 1)), 0, 0, false};
    float tanA = 0;
    for (const auto& [cx, cy] : {std::pair{x0, y0}, std::pair{x1 - 1, y0}, std::pair{x0, y1 - 1}, std::pair{x1 - 1, y1 - 1}}) {
      const float cosA = std::min(1.0f, dot(c.axis, view.ray(float(cx), float(cy))));
      tanA = std::max(tanA, std::sqrt(1 - cosA * cosA) / cosA);
    }
    c.tSafe = kernel.coneStart(view.eye, c.axis, tanA), c.tEnd = kernel.coneEnd(view.eye, c.axis, tanA);
    // A ray ends at most tEnd (1 + kConeSlack) / cos(angle) <= tEnd (1 + kConeSlack) sqrt(1 + tanA^2)
    // along it: if the tile's start lies beyond that, every ray ends before it starts.
    c.empty = c.tSafe > c.tEnd * (1 + kConeSlack) * std::sqrt(1 + tanA * tanA) * (1 + kConeSlack);
    return c;
  };
  std::vector<Cone> cones(tiles);

  // Preview frames keep, per lattice pixel (even x and y), its colour before output and its
  // normal (both zero for a miss): pass 2 compares and blends them.
  const bool preview = quality == FrameQuality::Preview;
  const int latticeW = camera.width / 2 + 1;
  std::vector<F3> latticeColour, latticeNormal;
  if (preview) {
    latticeColour.resize(std::size_t(latticeW) * (camera.height / 2 + 1));
    latticeNormal.resize(latticeColour.size());
  }
  auto lattice = [&](int x, int y) { return std::size_t(y >> 1) * latticeW + std::size_t(x >> 1); };

  // Traces the pixels xs[0, n) of row y of a tile and stores their colours and depths.
  auto traceRow = [&](const Cone& c, int y, const int* xs, int n) {
    RayKernel::Ray rays[kTile];
    for (int i = 0; i < n; ++i) {
      const F3 dir = view.ray(float(xs[i]), float(y));
      // The cone is empty beyond tEnd along its axis: along this ray, beyond tEnd / cos(angle).
      kernel.start(rays[i], view.eye, dir, c.tSafe, c.tEnd * (1 + kConeSlack) / std::max(dot(dir, c.axis), 1e-6f));
    }
    for (int i = 0; i < n; i += kGroup) kernel.trace(rays + i, std::min(kGroup, n - i));
    std::uint8_t bg[3];
    shader.store(shader.backgroundAt(float(y)), bg, srgb);
    for (int i = 0; i < n; ++i) {
      const float t = rays[i].hit;
      const std::size_t pi = std::size_t(y) * camera.width + xs[i];
      std::uint8_t* out = &frame.rgb[pi * 3];
      if (t < kInf) {
        frame.depth[pi] = t;
        if (preview && xs[i] % 2 == 0 && y % 2 == 0) {
          const std::size_t l = lattice(xs[i], y);
          latticeColour[l] = shader.hit(rays[i].d, t, &latticeNormal[l]);
          shader.store(latticeColour[l], out, srgb);
        } else {
          shader.store(shader.hit(rays[i].d, t), out, srgb);
        }
      } else {
        out[0] = bg[0], out[1] = bg[1], out[2] = bg[2];
      }
    }
  };

  // Pass 1: every pixel, or for a preview the lattice alone.
  pool.parallelFor(tiles, [&](std::size_t tile) {
    const Cone c = cones[tile] = coneOf(tile);
    const int step = preview ? 2 : 1;
    for (int y = c.y0; y < c.y1; y += c.empty ? 1 : step) {
      if (c.empty) {  // the whole tile, the pixels pass 2 would fill included
        std::uint8_t bg[3];
        shader.store(shader.backgroundAt(float(y)), bg, srgb);
        for (int x = c.x0; x < c.x1; ++x) std::copy(bg, bg + 3, &frame.rgb[(std::size_t(y) * camera.width + x) * 3]);
        continue;
      }
      int xs[kTile], n = 0;
      for (int x = c.x0; x < c.x1; x += step) xs[n++] = x;
      traceRow(c, y, xs, n);
    }
  });

  // Pass 2, previews: each other pixel from its lattice neighbours (left and right, above and
  // below, or the four diagonals), which pass 1 finished, so the result does not depend on the
  // thread count:
  // - all missed: background. A solid that fits between rays two pixels apart can vanish.
  // - all hit, within kPreviewDepthJump of each other, normals within kPreviewCosine and every
  //   output channel within kPreviewContrast: their mean colour (linear light) and depth.
  // - otherwise traced. (Starting those rays just before their neighbours' nearest hit, when
  //   all hit, saved 6% of the instructions and let thin parts in front vanish: not done.)
  // The error against the Interactive frame is measured over whole frames (test_raycast.cpp).
  if (preview)
    pool.parallelFor(tiles, [&](std::size_t tile) {
      const Cone& c = cones[tile];
      if (c.empty) return;
      for (int y = c.y0; y < c.y1; ++y) {
        std::uint8_t bg[3];
        shader.store(shader.backgroundAt(float(y)), bg, srgb);
        int xs[kTile], n = 0;
        for (int x = c.x0 + (y % 2 ? 0 : 1); x < c.x1; x += y % 2 ? 1 : 2) {
          const std::size_t pi = std::size_t(y) * camera.width + x;
          const int dx = x % 2, dy = y % 2;
          if (x + dx >= camera.width || y + dy >= camera.height) {
            xs[n++] = x;
            continue;
          }
          // The neighbours' pixel and lattice indices; all missed, all hit or some of each.
          std::size_t q[4], l[4];
          int count = 0, hits = 0;
          for (int sy = -dy; sy <= dy; sy += 2)
            for (int sx = -dx; sx <= dx; sx += 2) {
              q[count] = pi + std::ptrdiff_t(sy) * camera.width + sx;
              l[count] = lattice(x + sx, y + sy);
              hits += frame.depth[q[count++]] < kInf ? 1 : 0;
            }
          std::uint8_t* out = &frame.rgb[pi * 3];
          if (hits == 0) {
            out[0] = bg[0], out[1] = bg[1], out[2] = bg[2];
            continue;
          }
          if (hits == count) {
            float nearest = kInf, farthest = 0, depthSum = 0;
            F3 colourSum{};
            int lo[3] = {255, 255, 255}, hi[3] = {0, 0, 0};
            bool agree = true;
            for (int k = 0; k < count; ++k) {
              const float t = frame.depth[q[k]];
              nearest = std::min(nearest, t), farthest = std::max(farthest, t), depthSum += t;
              colourSum = colourSum + latticeColour[l[k]];
              agree = agree && dot(latticeNormal[l[0]], latticeNormal[l[k]]) >= kPreviewCosine;
              for (int ch = 0; ch < 3; ++ch) {
                const int v = frame.rgb[q[k] * 3 + ch];
                lo[ch] = std::min(lo[ch], v), hi[ch] = std::max(hi[ch], v);
              }
            }
            for (int ch = 0; ch < 3; ++ch) agree = agree && hi[ch] - lo[ch] <= kPreviewContrast;
            if (agree && farthest - nearest <= kPreviewDepthJump) {
              frame.depth[pi] = depthSum / float(count);
              shader.store(colourSum * (1.0f / float(count)), out, srgb);
              continue;
            }
          }
          xs[n++] = x;
        }
        traceRow(c, y, xs, n);
      }
    });
  if (!still) return frame;

  // Anti-aliasing reads the finished first pass (neighbours across tiles included) and writes
  // only its own tile's colours, so the result does not depend on the thread count. Its rays
  // start from the eye (the tile's cone does not hold rays off the pixel centres).
  std::vector<std::uint8_t> resolved = frame.rgb;
  pool.parallelFor(tiles, [&](std::size_t tile) {
    const int x0 = int(tile % tilesX) * kTile, y0 = int(tile / tilesX) * kTile;
    const int x1 = std::min(x0 + kTile, camera.width), y1 = std::min(y0 + kTile, camera.height);
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        if (!isEdge(frame, x, y)) continue;
        RayKernel::Ray rays[kAaSamples];
        for (int s = 0; s < kAaSamples; ++s)
          kernel.start(rays[s], view.eye, view.ray(float(x) + kAaOffsets[s][0], float(y) + kAaOffsets[s][1]), 0, kInf);
        kernel.trace(rays, kAaSamples);
        F3 sum{};
        for (int s = 0; s < kAaSamples; ++s)
          sum = sum + (rays[s].hit < kInf ? shader.hit(rays[s].d, rays[s].hit) : shader.backgroundAt(float(y) + kAaOffsets[s][1]));
        shader.store(sum * (1.0f / kAaSamples), &resolved[(std::size_t(y) * camera.width + x) * 3], srgb);
      }
  });
  frame.rgb = std::move(resolved);
  return frame;
}

Frame render(const Volume& volume, const Camera& camera, Shading shading, ThreadPool& pool, FrameQuality quality,
             double thicknessMinVu) {
  camera.validate();
  return render(RaycastAccel(volume, pool), camera, shading, pool, quality, thicknessMinVu);
}

}  // namespace marzipan
