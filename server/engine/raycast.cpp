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
#include "raycast.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <sstream>

#include "color_space.hpp"
#include "errors.hpp"
#include "raycast_kernel.hpp"
#include "thickness.hpp"

namespace marzipan {

using namespace raycasting;

namespace {

constexpr int kTile = 16;  // even: a tile holds whole 2x2 blocks of a preview
constexpr int kGroup = 4;  // rays traced together, interleaved
// Preview frames (pass 2 in render): what lets a pixel be blended from its lattice neighbours.
// 8 vu rather than 2: a surface turning away near a silhouette is blended too (0.92 vu of depth
// error at most on the benchmark's sphere, no visible change), 19% fewer instructions there.
constexpr float kPreviewDepthJump = 8.0f;  // vu between the nearest and farthest neighbour hit
constexpr float kPreviewCosine = 0.97f;    // between their normals (about 14 degrees)
constexpr int kPreviewContrast = 12;       // per output channel, 0-255
constexpr float kGradientErrorWhite = 0.1f;

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
