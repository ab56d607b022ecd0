// The per-brick channels of a Volume beside its distances (volume.hpp, channels.hpp): colour and
// mask (texels read one at a time or gathered over a box, the base colour, a brick's texels made
// canonical, and the extension that gives a voxel entering the band the texel of the old surface
// it came from), and the tools' drift bound (BrickDrift), kept in tiles of its own.
#include "volume.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <utility>

#include "errors.hpp"
#include "stencil.hpp"

namespace marzipan {

Texel Volume::texel(Int3 p) const {
  if (paintedBricks_ == 0 || p.x < 0 || p.y < 0 || p.z < 0 || p.x >= dims_.x || p.y >= dims_.y || p.z >= dims_.z)
    return texelOf(base_);
  const BrickPaint* bp = brickPaint(Bricks::brickOf(p));
  return bp ? bp->t[Bricks::indexOf(p)] : texelOf(base_);
}

void Volume::gatherTexels(const Box& box, Texel* out) const {
  if (box.empty()) return;
  const Int3 s = box.size();
  const std::size_t sx = std::size_t(s.x), sxy = sx * std::size_t(s.y);
  std::fill(out, out + sxy * std::size_t(s.z), texelOf(base_));
  const Box inside = box.intersect(domain());
  if (paintedBricks_ == 0 || inside.empty()) return;
  const Box bricks = Bricks::bricksOf(inside);
  for (int bz = bricks.lo.z; bz < bricks.hi.z; ++bz)
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const BrickPaint* bp = brickPaint({bx, by, bz});
        if (!bp) continue;
        const Box here = Bricks::box({bx, by, bz}).intersect(inside);
        const Int3 o = Bricks::origin({bx, by, bz});
        for (int z = here.lo.z; z < here.hi.z; ++z)
          for (int y = here.lo.y; y < here.hi.y; ++y) {
            const Texel* from = bp->t + Bricks::index(here.lo.x - o.x, y - o.y, z - o.z);
            Texel* to = out + std::size_t(here.lo.x - box.lo.x) + sx * std::size_t(y - box.lo.y) +
                        sxy * std::size_t(z - box.lo.z);
            std::copy(from, from + (here.hi.x - here.lo.x), to);
          }
      }
}

void Volume::setBaseColor(Rgb8 c) {
  if (paintedBricks_ != 0)
    throw EngineError(ErrorKind::InvalidArgument, "color", "the base colour can only be set before anything is painted");
  base_ = c;
}

std::shared_ptr<const BrickPaint> Volume::canonicalPaint(std::shared_ptr<BrickPaint> paint) const {
  // As 32-bit words, without an early exit, so that the loop vectorizes.
  static_assert(sizeof(Texel) == sizeof(std::uint32_t));
  std::uint32_t words[kBrickVoxels];
  std::memcpy(words, paint->t, sizeof words);
  const std::uint32_t base = std::bit_cast<std::uint32_t>(texelOf(base_));
  std::uint32_t differs = 0, weights = 0;
  for (const std::uint32_t w : words) {
    differs |= w ^ base;
    weights |= w;
  }
  const bool masked = std::bit_cast<Texel>(weights).mask != 0;
  if (differs == 0) return nullptr;
  paint->masked = masked;
  return paint;
}

Vec3 Volume::nearestOldSurface(Vec3 p, Vec3 otherwise) const {
  constexpr double kReach = 32;
  double best = kReach;
  Vec3 found = otherwise;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        const Vec3 dir = normalized(Vec3{double(dx), double(dy), double(dz)});
        // Sphere tracing: |d| is at most the distance to the surface, also where it is clamped.
        for (double t = 0; t < best;) {
          const Vec3 x = p + dir * t;
          const double d0 = sample(x);
          if (std::fabs(d0) < band_ - 0.5) {
            const Vec3 g0 = gradient(x);
            best = t;
            found = length(g0) > 0 ? x - g0 * (d0 / length(g0)) : x;
            break;
          }
          t += std::max(std::fabs(d0) - 0.5, 0.5);
        }
      }
  return found;
}

void Volume::extendChannels(std::vector<BrickChange>& changes) const {
  if (paintedBricks_ == 0 || changes.empty()) return;
  // The new field: a changed brick's `after`, this volume elsewhere.
  std::vector<std::pair<std::uint64_t, std::size_t>> index;
  index.reserve(changes.size());
  const auto key = [](Int3 b) {
    return std::uint64_t(std::uint32_t(b.z)) << 42 | std::uint64_t(std::uint32_t(b.y)) << 21 | std::uint32_t(b.x);
  };
  for (std::size_t i = 0; i < changes.size(); ++i) index.push_back({key(changes[i].brick), i});
  std::sort(index.begin(), index.end());
  const auto newAt = [&](Int3 p) -> float {
    if (p.x < 0 || p.y < 0 || p.z < 0 || p.x >= dims_.x || p.y >= dims_.y || p.z >= dims_.z) return band_;
    const Int3 b = Bricks::brickOf(p);
    const auto it = std::lower_bound(index.begin(), index.end(), std::pair<std::uint64_t, std::size_t>{key(b), 0});
    if (it == index.end() || it->first != key(b)) return at(p);
    const BrickRef& r = changes[it->second].after;
    return r.data ? r.data->v[Bricks::indexOf(p)] : (r.inside ? -band_ : band_);
  };
  const Texel base = texelOf(base_);
  for (BrickChange& c : changes) {
    if (!c.after.data) continue;
    const float* before = c.before.data ? c.before.data->v : nullptr;
    const float* after = c.after.data->v;
    const Int3 o = Bricks::origin(c.brick);
    // newAt, without the search for the neighbours within this brick (most of them).
    const auto newNear = [&](Int3 q) -> float {
      const Int3 l = q - o;
      if (l.x < 0 || l.y < 0 || l.z < 0 || l.x >= kBrickSide || l.y >= kBrickSide || l.z >= kBrickSide ||
          q.x >= dims_.x || q.y >= dims_.y || q.z >= dims_.z)
        return newAt(q);
      return after[Bricks::index(l)];
    };
    std::shared_ptr<BrickPaint> now;
    for (int i = 0; i < kBrickVoxels; ++i) {
      if (!(std::fabs(after[i]) < band_) || (before && std::fabs(before[i]) < band_)) continue;
      const Int3 p = o + Bricks::local(i);
      const Vec3 g = GradStencil::around(p, newNear).gradient();
      const double len = length(g);
      const Vec3 n = len > 0 ? g * (1 / len) : Vec3{};
      Vec3 q = Vec3{double(p.x), double(p.y), double(p.z)} - n * double(after[i]);
      // From the new surface back to the old one: along the new normal while the old field is
      // clamped there (a surface that grew by more than the band), then to the old foot point.
      bool reached = false;
      for (int step = 0; step < 16 && !reached; ++step) {
        const double d0 = sample(q);
        if (std::fabs(d0) < band_ - 0.5 || n == Vec3{}) {
          const Vec3 g0 = gradient(q);
          if (length(g0) > 0) q = q - g0 * (d0 / length(g0));
          reached = true;
        } else {
          q = q - n * d0;
        }
      }
      // The normal's line can miss the old surface (the upper side of a blob that overhangs
      // it): then the old surface point nearest the voxel along one of 26 directions.
      if (!reached) q = nearestOldSurface(Vec3{double(p.x), double(p.y), double(p.z)}, q);
      const Texel t = texel({int(std::floor(q.x + 0.5)), int(std::floor(q.y + 0.5)), int(std::floor(q.z + 0.5))});
      const Texel had = texelSoFar(now.get(), c.after.paint.get(), base, i);
      if (t == had) continue;
      setTexel(now, c.after.paint.get(), base, i, t);
    }
    if (now) c.after.paint = canonicalPaint(std::move(now));
  }
  std::erase_if(changes, [](const BrickChange& c) { return c.before == c.after; });
}

BrickDrift Volume::driftOf(const DriftSlot& d, Int3 b) {
  if (d.hi[0] == 0) return {};
  const Int3 o = Bricks::origin(b);
  return {d.move, {{o.x + d.lo[0], o.y + d.lo[1], o.z + d.lo[2]}, {o.x + d.hi[0], o.y + d.hi[1], o.z + d.hi[2]}}};
}

BrickDrift Volume::brickDrift(Int3 b) const {
  if (driftTiles_.empty()) return {};
  const DriftTile* t = driftTiles_[tileIndex(b)].get();
  return t ? driftOf(t->slots[slotInTile(b)], b) : BrickDrift{};
}

void Volume::brickDrifts(const Box& bricks, BrickDrift* out) const {
  const std::size_t n = std::size_t(bricks.voxels());
  std::fill(out, out + n, BrickDrift{});
  if (driftTiles_.empty()) return;
  std::size_t k = 0;
  for (int z = bricks.lo.z; z < bricks.hi.z; ++z)
    for (int y = bricks.lo.y; y < bricks.hi.y; ++y)
      for (int x = bricks.lo.x; x < bricks.hi.x; ++x, ++k)
        if (const DriftTile* t = driftTiles_[tileIndex({x, y, z})].get()) out[k] = driftOf(t->slots[slotInTile({x, y, z})], {x, y, z});
}

void Volume::setBrickDrift(std::span<const std::pair<Int3, BrickDrift>> drifts) {
  if (drifts.empty()) return;
  if (driftTiles_.empty()) driftTiles_.assign(tiles_.size(), nullptr);
  // Tile by tile in the given order: each run of one tile's bricks copies it once.
  std::size_t i = 0;
  while (i < drifts.size()) {
    const std::size_t ti = tileIndex(drifts[i].first);
    auto t = driftTiles_[ti] ? std::make_shared<DriftTile>(*driftTiles_[ti]) : std::make_shared<DriftTile>();
    for (; i < drifts.size() && tileIndex(drifts[i].first) == ti; ++i) {
      const auto& [b, drift] = drifts[i];
      DriftSlot& d = t->slots[slotInTile(b)];
      t->present -= d.hi[0] != 0 ? 1 : 0;
      d = {};
      const Box in = drift.box.intersect(Bricks::box(b));
      if (in.empty()) continue;
      const Int3 o = Bricks::origin(b);
      d.move = drift.move;
      for (int a = 0; a < 3; ++a) {
        d.lo[a] = std::uint8_t(in.lo[a] - o[a]);
        d.hi[a] = std::uint8_t(in.hi[a] - o[a]);
      }
      ++t->present;
    }
    driftTiles_[ti] = t->present != 0 ? std::move(t) : nullptr;
  }
}

std::size_t Volume::driftedBricks() const {
  std::size_t n = 0;
  for (const auto& t : driftTiles_) n += t ? std::size_t(t->present) : 0;
  return n;
}

}  // namespace marzipan
