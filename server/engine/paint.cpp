// Paint and mask strokes (paint.hpp): brick by brick, each stored brick the dabs may reach is
// read with a ring of one voxel (for the normals), its band voxels' alphas found at their foot
// points, and a new BrickPaint made where a texel changes.
#include "paint.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "errors.hpp"
#include "progress.hpp"

namespace marzipan {

namespace {

// Bricks to paint per piece of work on the pool: a piece is a few tens of microseconds.
constexpr std::size_t kBricksPerPiece = 16;

struct PaintDab {
  Vec3 center;
  double weight;
  Box reach;  // the voxels whose foot point may lie within the radius
  float x, y, z, w;  // center and weight in single precision, for Falloff
};

// In single precision: the dabs' loop runs it a few thousand times per dab, and a float's
// 1e-4 vu at a 1024-voxel side is far below what an 8-bit channel resolves.
class Falloff {
 public:
  explicit Falloff(const PaintSettings& st)
      : radius2_(float(st.radius * st.radius)),
        inner_(float(st.hardness * st.radius)),
        inner2_(inner_ * inner_),
        perWidth_(float(1 / (st.radius - st.hardness * st.radius))),
        strength_(float(st.strength)) {}
  // The alpha of a dab of weight w at offset (x, y, z) from its centre.
  float alpha(float x, float y, float z, float w) const {
    const float rho2 = x * x + y * y + z * z;
    if (!(rho2 < radius2_)) return 0;
    if (rho2 <= inner2_) return strength_ * w;
    const float t = (std::sqrt(rho2) - inner_) * perWidth_;
    const float s = 1 - t * t;
    return strength_ * w * s * s;
  }

 private:
  float radius2_, inner_, inner2_, perWidth_, strength_;
};

// Rounded to nearest, halves up: floor(x + 0.5), lround for the non-negative values here.
std::uint8_t toward(std::uint8_t from, double to, double e) {
  return std::uint8_t(std::clamp(double(from) + e * (to - double(from)), 0.0, 255.0) + 0.5);
}

// The distance from p to the nearest point of box (0 inside it).
double distanceToBox(Vec3 p, const Box& b) {
  double s = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = b.lo[a], hi = b.hi[a] - 1;
    const double d = p[a] < lo ? lo - p[a] : p[a] > hi ? p[a] - hi : 0;
    s += d * d;
  }
  return std::sqrt(s);
}

// tinted(), here where the dabs' loop can inline it; an unmasked texel skips the division.
Texel tint(Texel t, Rgb8 color, double e) {
  const double k = t.mask == 0 ? e : e * (1 - double(t.mask) / 255);
  return {toward(t.r, color.r, k), toward(t.g, color.g, k), toward(t.b, color.b, k), t.mask};
}

// The texel t painted by e (> 0) of the way that is left.
Texel painted(Texel t, const PaintSettings& st, double e) {
  switch (st.mode) {
    case PaintMode::Color:
      return tint(t, st.color, e);
    case PaintMode::MaskAdd:
      return {t.r, t.g, t.b, toward(t.mask, 255, e)};
    case PaintMode::MaskErase:
      return {t.r, t.g, t.b, toward(t.mask, 0, e)};
  }
  return t;
}

// The distances of a box already gathered (data null: none, each brick gathers its own).
struct Field {
  const float* data = nullptr;
  Box box;
};

// A stroke whose region grown by one holds at most this many voxels is gathered once: a
// brick's own gather reads its 26 neighbours' faces in rows of one to eight voxels, several
// times the cost per voxel of whole bricks (a radius-8 dab: 15k voxels, 0.16M instructions
// gathered brick by brick).
constexpr std::int64_t kGatherOnce = std::int64_t(64) * 64 * 64;

// A thread's scratch for paintBrick's rows, kept between bricks so that a row allocates nothing.
std::vector<std::pair<float, float>>& scratchAcross() {
  thread_local std::vector<std::pair<float, float>> across;
  return across;
}

// The new channels of stored brick b, or null when no texel changes.
// A voxel's foot point lies within band of it, so a dab reaches only the voxels within
// radius + band of its centre: `near` are the dabs that reach some voxel of brick b.
std::shared_ptr<BrickPaint> paintBrick(const Volume& vol, Int3 b, const PaintSettings& st, const Falloff& falloff,
                                       const Field& field, std::span<const PaintDab> dabs, std::span<const PaintDab> memory,
                                       std::vector<const PaintDab*>& near, std::vector<const PaintDab*>& remembered) {
  const Box box = Bricks::box(b);
  const double reach = st.radius + vol.band();
  near.clear();
  remembered.clear();
  for (const PaintDab& d : dabs)
    if (distanceToBox(d.center, box) < reach) near.push_back(&d);
  if (near.empty()) return nullptr;
  for (const PaintDab& d : memory)
    if (distanceToBox(d.center, box) < reach) remembered.push_back(&d);
  // Only the voxels within `reach` of a near dab's centre can be reached: those of the brick
  // inside the near dabs' boxes, and per row the hull of the dabs' chords through the balls of
  // that radius, a voxel wider on each side against rounding (the exact test below decides).
  Box sub{box.hi, box.lo};
  for (const PaintDab* dab : near)
    for (int a = 0; a < 3; ++a) {
      sub.lo[a] = std::min(sub.lo[a], dab->reach.lo[a]);
      sub.hi[a] = std::max(sub.hi[a], dab->reach.hi[a]);
    }
  sub = sub.intersect(box);
  if (sub.empty()) return nullptr;
  float own[(kBrickSide + 2) * (kBrickSide + 2) * (kBrickSide + 2)];
  const Box read = field.data ? field.box : sub.grown(1);
  if (!field.data) vol.gather(read, own);
  const float* const d = field.data ? field.data : own;
  const Int3 size = read.size();
  const int sx = size.x, sxy = size.x * size.y;
  const float band = vol.band();
  const BrickPaint* old = vol.brickPaint(b);
  const Texel base = texelOf(vol.baseColor());
  const Int3 o = Bricks::origin(b);
  std::shared_ptr<BrickPaint> now;
  const double reach2 = reach * reach;
  const float radius = float(st.radius);
  // Per row, each near dab's centre x and squared distance across the row (dy^2 + dz^2).
  std::vector<std::pair<float, float>>& across = scratchAcross();
  for (int z = sub.lo.z; z < sub.hi.z; ++z)
    for (int y = sub.lo.y; y < sub.hi.y; ++y) {
      int xlo = sub.hi.x, xhi = sub.lo.x - 1;
      across.clear();
      for (const PaintDab* dab : near) {
        const double dy = y - dab->center.y, dz = z - dab->center.z;
        const double rest = reach2 - dy * dy - dz * dz;
        if (!(rest >= 0)) continue;
        across.emplace_back(dab->x, float(dy * dy + dz * dz));
        const double half = std::sqrt(rest);
        xlo = std::min(xlo, int(std::max(double(sub.lo.x), std::floor(dab->center.x - half) - 1)));
        xhi = std::max(xhi, int(std::min(double(sub.hi.x - 1), std::ceil(dab->center.x + half) + 1)));
      }
      const int rowStart = sx * (y - read.lo.y) + sxy * (z - read.lo.z) - read.lo.x;
      for (int x = xlo; x <= xhi; ++x) {
        const int i = rowStart + x;
        const float phi = d[i];
        if (!(std::fabs(phi) <= band)) continue;
        const float most = (radius + std::fabs(phi)) * (radius + std::fabs(phi));
        bool reached = false;
        for (const auto& [cx, yz2] : across) reached = reached || (float(x) - cx) * (float(x) - cx) + yz2 < most;
        if (!reached) continue;
        const float gx = d[i + 1] - d[i - 1], gy = d[i + sx] - d[i - sx], gz = d[i + sxy] - d[i - sxy];
        const float len2 = gx * gx + gy * gy + gz * gz;
        const float step = len2 > 0 ? phi / std::sqrt(len2) : 0.0f;
        const float qx = float(x) - gx * step, qy = float(y) - gy * step, qz = float(z) - gz * step;
        float a = 0;
        for (const PaintDab* dab : near) a = std::max(a, falloff.alpha(qx - dab->x, qy - dab->y, qz - dab->z, dab->w));
        if (!(a > 0)) continue;
        float m = 0;
        for (const PaintDab* dab : remembered) m = std::max(m, falloff.alpha(qx - dab->x, qy - dab->y, qz - dab->z, dab->w));
        if (!(a > m)) continue;
        const int k = Bricks::index(x - o.x, y - o.y, z - o.z);
        const Texel t = texelSoFar(now.get(), old, base, k);
        const Texel n = painted(t, st, (double(a) - m) / (1 - double(m)));
        if (n == t) continue;
        setTexel(now, old, base, k, n);
      }
    }
  return now;
}

// Sets every stored brick's weights to weight(w); `skip` tells a brick whose channels (null
// when it has none) cannot change, without reading its texels.
template <class Weight, class Skip>
Edit mapMask(Volume& vol, Weight weight, Skip skip) {
  Progress* const progress = Progress::current();
  if (progress) progress->check();
  const Texel base = texelOf(vol.baseColor());
  Edit edit;
  edit.region = vol.domain();
  vol.forEachPresentBrick([&](Int3 b, const Brick&) {
    const BrickPaint* old = vol.brickPaint(b);
    if (skip(old)) return;
    auto now = std::make_shared<BrickPaint>();
    bool changed = false;
    for (int i = 0; i < kBrickVoxels; ++i) {
      Texel t = old ? old->t[i] : base;
      const std::uint8_t w = weight(t.mask);
      changed = changed || w != t.mask;
      t.mask = w;
      now->t[i] = t;
    }
    if (!changed) return;
    BrickRef before = vol.brick(b);
    BrickRef after = before;
    after.paint = vol.canonicalPaint(std::move(now));
    edit.changes.push_back({b, std::move(before), std::move(after)});
  });
  vol.publish(edit.changes, true);
  if (progress) progress->advance(1);
  return edit;
}

}  // namespace

Edit maskClear(Volume& vol) {
  return mapMask(vol, [](std::uint8_t) { return std::uint8_t(0); }, [](const BrickPaint* p) { return !p || !p->masked; });
}

Edit maskFill(Volume& vol) {
  return mapMask(vol, [](std::uint8_t) { return std::uint8_t(255); }, [](const BrickPaint*) { return false; });
}

Edit maskInvert(Volume& vol) {
  return mapMask(vol, [](std::uint8_t w) { return std::uint8_t(255 - w); }, [](const BrickPaint*) { return false; });
}

Texel tinted(Texel t, Rgb8 color, double e) { return tint(t, color, e); }

void checkPaintSettings(const PaintSettings& st) {
  requireRange(st.radius, 0.5, kMaxDomainSide, "radius");
  requireFinite(st.strength, "strength");
  if (!(st.strength > 0 && st.strength <= 1)) throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  if (!(st.hardness >= 0 && st.hardness < 1)) throw EngineError(ErrorKind::InvalidArgument, "hardness", "must be in [0, 1)");
  if (st.mode != PaintMode::Color && st.mode != PaintMode::MaskAdd && st.mode != PaintMode::MaskErase)
    throw EngineError(ErrorKind::InvalidArgument, "mode", "must be color, mask add or mask erase");
}

Edit paintStroke(Volume& vol, const PaintSettings& st, std::span<const StrokeDab> dabs,
                 std::span<const StrokeDab> memory, ThreadPool& pool) {
  checkPaintSettings(st);
  const double reach = st.radius + vol.band() + 1;
  auto prepare = [&](std::span<const StrokeDab> from, bool check) {
    std::vector<PaintDab> out;
    for (const StrokeDab& d : from) {
      if (check) {
        if (!isFinite(d.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
        if (!(d.weight > 0 && d.weight <= 1)) throw EngineError(ErrorKind::InvalidArgument, "weight", "must be in (0, 1]");
      } else if (!isFinite(d.center) || !(d.weight > 0 && d.weight <= 1)) {
        continue;
      }
      const Box box = boxAround(d.center, {reach, reach, reach}).intersect(vol.domain());
      if (box.empty()) {
        if (check) throw EngineError(ErrorKind::OutOfDomain, "center", "the tool's region lies outside the volume");
        continue;
      }
      out.push_back({d.center, d.weight, box, float(d.center.x), float(d.center.y), float(d.center.z), float(d.weight)});
    }
    return out;
  };
  const std::vector<PaintDab> mine = prepare(dabs, true), remembered = prepare(memory, false);
  Edit edit;
  if (mine.empty()) return edit;
  Box region = mine.front().reach;
  for (const PaintDab& d : mine)
    for (int a = 0; a < 3; ++a) {
      region.lo[a] = std::min(region.lo[a], d.reach.lo[a]);
      region.hi[a] = std::max(region.hi[a], d.reach.hi[a]);
    }
  // The stored bricks some dab reaches, in z, y, x order.
  std::vector<Int3> bricks;
  const Box span = Bricks::bricksOf(region);
  for (int bz = span.lo.z; bz < span.hi.z; ++bz)
    for (int by = span.lo.y; by < span.hi.y; ++by)
      for (int bx = span.lo.x; bx < span.hi.x; ++bx) {
        const Int3 b{bx, by, bz};
        float uniform;
        if (!vol.brickData(b, &uniform)) continue;
        const Box box = Bricks::box(b);
        if (std::any_of(mine.begin(), mine.end(),
                        [&](const PaintDab& d) { return distanceToBox(d.center, box) < st.radius + vol.band(); }))
          bricks.push_back(b);
      }
  const Falloff falloff(st);
  Field field;
  thread_local std::vector<float> gathered;
  if (region.grown(1).voxels() <= kGatherOnce) {
    field.box = region.grown(1);
    gathered.resize(std::size_t(field.box.voxels()));
    vol.gather(field.box, gathered.data());
    field.data = gathered.data();
  }
  Progress* const progress = Progress::current();
  std::vector<std::shared_ptr<BrickPaint>> now(bricks.size());
  const std::size_t pieces = (bricks.size() + kBricksPerPiece - 1) / kBricksPerPiece;
  auto run = [&](std::size_t piece) {
    if (progress) progress->check();
    std::vector<const PaintDab*> near, before;
    const std::size_t end = std::min(bricks.size(), (piece + 1) * kBricksPerPiece);
    for (std::size_t k = piece * kBricksPerPiece; k < end; ++k)
      now[k] = paintBrick(vol, bricks[k], st, falloff, field, mine, remembered, near, before);
  };
  if (pieces > 1 && pool.threads() > 1) {
    pool.parallelFor(pieces, run);
  } else {
    for (std::size_t piece = 0; piece < pieces; ++piece) run(piece);
  }
  for (std::size_t k = 0; k < bricks.size(); ++k) {
    if (!now[k]) continue;
    BrickRef old = vol.brick(bricks[k]);
    BrickRef after = old;
    after.paint = vol.canonicalPaint(std::move(now[k]));
    if (after == old) continue;
    edit.changes.push_back({bricks[k], std::move(old), std::move(after)});
  }
  vol.publish(edit.changes, true);
  edit.region = region;
  if (progress) progress->advance(1);
  return edit;
}

Edit paint(Volume& vol, const PaintSettings& st, Vec3 center, ThreadPool& pool) {
  const StrokeDab dab(center);
  return paintStroke(vol, st, {&dab, 1}, {}, pool);
}

}  // namespace marzipan
