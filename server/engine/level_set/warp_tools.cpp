// The warp tools' entry points (../level_set.hpp, warps): their checks, each tool's velocity
// field (Velocity, warp_fields.hpp) from its parameters, a snake hook move's start on the tip,
// and the bounds of |grad v| the callers size sub-steps by. The warp itself is applyWarp's
// (warp.cpp). Points are volume coordinates (vu).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

#include "engine/errors.hpp"
#include "engine/level_set/warp_passes.hpp"

namespace marzipan {

using namespace level_set::warp;

namespace {

void checkBase(const Volume& vol, const Volume& base) {
  if (!(vol.dims() == base.dims()) || vol.band() != base.band())
    throw EngineError(ErrorKind::InvalidArgument, "base", "must have the volume's dimensions and band");
}

void checkAnchor(const Volume& vol, Vec3 anchor) {
  if (!isFinite(anchor)) throw EngineError(ErrorKind::InvalidArgument, "anchor", "must be three finite numbers");
  const Int3 n = vol.dims();
  for (int a = 0; a < 3; ++a)
    if (!(anchor[a] >= 0 && anchor[a] <= n[a] - 1))
      throw EngineError(ErrorKind::OutOfDomain, "anchor", "must lie in the volume");
}

void checkRadius(double radius) { requireRange(radius, kMinWarpRadius, kMaxWarpRadius, "radius"); }

Vec3 unitAxis(Vec3 axis) {
  if (!isFinite(axis) || !(length(axis) > 1e-9))
    throw EngineError(ErrorKind::InvalidArgument, "axis", "must be a finite non-zero vector");
  return normalized(axis);
}

Velocity affine(Vec3 anchor, double radius) {
  Velocity v;
  v.kind = Velocity::Kind::Affine;
  v.anchor = anchor;
  v.setSupport(radius, kPlateau);
  return v;
}

// Sets v.scale so that the flow carries the anchor to anchor + d within kWarpAnchorTolerance
// (a secant search from scale 1), or throws EngineError (field "d").
void landAnchor(Velocity& v, Vec3 anchor, Vec3 d) {
  if (!(length(d) > 0)) return;
  const Vec3 target = anchor + d;
  const auto miss = [&](double scale) {
    Velocity w = v;
    w.scale = scale;
    return dot(w.flow(anchor, w.substeps(), 1) - target, normalized(d));
  };
  double s0 = 1, m0 = miss(s0);
  double s1 = 1.1, m1 = miss(s1);
  for (int i = 0; i < 24 && std::fabs(m0) > 0.01 * kWarpAnchorTolerance && m1 != m0; ++i) {
    const double s2 = std::max(0.0, s1 - m1 * (s1 - s0) / (m1 - m0));
    s0 = s1, m0 = m1, s1 = s2, m1 = miss(s2);
    if (std::fabs(m1) < std::fabs(m0)) std::swap(s0, s1), std::swap(m0, m1);
  }
  v.scale = s0;
  if (!(length(v.flow(anchor, v.substeps(), 1) - target) <= kWarpAnchorTolerance))
    throw EngineError(ErrorKind::InvalidArgument, "d", "the anchor cannot be carried to its target");
}

// A grab's velocity (its parameters checked but the anchor's place, which the caller checks
// against its volume): d at most kMaxWarpTravelPerRadius times `radius`, the brush's, and the
// support `support` vu (the brush's radius but for a snake hook's young tentacle,
// snakeHookVelocity()) and the plateau's radius `ball` vu (0 for a grab).
Velocity grabVelocity(Vec3 anchor, Vec3 d, double radius, double ball, double support) {
  if (!isFinite(anchor)) throw EngineError(ErrorKind::InvalidArgument, "anchor", "must be three finite numbers");
  checkRadius(radius);
  if (!isFinite(d)) throw EngineError(ErrorKind::InvalidArgument, "d", "must be three finite numbers");
  if (!(length(d) <= kMaxWarpTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "d", "must be at most 8 radii long");
  Velocity v;
  v.anchor = anchor;
  v.seg = d;
  v.segLength2 = dot(d, d);
  v.segLength = std::sqrt(v.segLength2);
  if (v.segLength > 0) v.segAxis = d / v.segLength;
  v.plateauBall = ball;
  v.setSupport(support, ball / support);
  // Along the segment v = scale * d: scale 1 lands the anchor on anchor + d up to rounding.
  landAnchor(v, anchor, d);
  return v;
}

// How far a snake hook's plateau ball sinks into the tip (snakeHookVelocity()), as a share of
// its radius: with the ball sunk whole, its centre at `centre`, the clay's least distance at
// eight points a radius from the centre across the move (`along`, a unit vector), over
// kSinkClearance radii (at most the band, where distances stop), clamped to [0, 1]. The tip of
// a tentacle thinner than the support's radius sinks the ball whole; a body wider than that
// (the sphere a tentacle starts from, the tentacle's own side at a turn) keeps it at the surface.
constexpr double kSinkClearance = 0.25;
// The sunk ball's radius is the tip's (tipRadius()), at most the plateau's and at least this
// share of it (a tentacle pinched thin elsewhere keeps the ball from shrinking with it).
constexpr double kLeastBall = 0.5;
// The support of a move whose ball sinks only in part, by the share `share` (0 < share < 1):
// 1 + kYoungWidening (1 - share) radii, at most kMaxWarpRadius.
constexpr double kYoungWidening = 0.5;
// The eight unit directions across a move (`along`, a unit vector), 45 degrees apart: where the
// tip's section is sampled.
std::array<Vec3, 8> raysAcross(Vec3 along) {
  const Vec3 e1 = normalized(cross(along, std::fabs(along.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
  const Vec3 e2 = cross(along, e1);
  std::array<Vec3, 8> rays;
  for (int k = 0; k < 8; ++k) {
    const double angle = k * std::numbers::pi / 4;
    rays[std::size_t(k)] = e1 * std::cos(angle) + e2 * std::sin(angle);
  }
  return rays;
}

double sinkShare(const Volume& vol, Vec3 centre, Vec3 along, double radius) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const Vec3& ray : raysAcross(along)) nearest = std::min(nearest, vol.sample(centre + ray * radius));
  return std::clamp(nearest / std::min(kSinkClearance * radius, double(vol.band())), 0.0, 1.0);
}

// The tip's least radius across the move (`along`, a unit vector) at `centre` (inside the clay):
// the distance to the surface along eight rays across the move, at most `most`.
double tipRadius(const Volume& vol, Vec3 centre, Vec3 along, double most) {
  double least = most;
  for (const Vec3& ray : raysAcross(along)) {
    // Steps of half a voxel to the first point outside, then halvings to 1/8192 vu.
    double in = 0, out = -1;
    for (double t = 0.5; t < least + 0.5; t += 0.5) {
      if (vol.sample(centre + ray * t) >= 0) {
        out = t;
        break;
      }
      in = t;
    }
    if (out < 0) continue;
    for (int i = 0; i < 12; ++i) {
      const double mid = 0.5 * (in + out);
      (vol.sample(centre + ray * mid) < 0 ? in : out) = mid;
    }
    least = std::min(least, 0.5 * (in + out));
  }
  return least;
}

// The velocity of snakeHook(vol, anchor, target, radius): a grab of vol from the surface point
// it starts from, its segment sunk into the tip (sinkShare()).
Velocity snakeHookVelocity(const Volume& vol, Vec3 anchor, Vec3 target, double radius) {
  if (!isFinite(target)) throw EngineError(ErrorKind::InvalidArgument, "target", "must be three finite numbers");
  requireRange(radius, kMinSnakeHookRadius, kMaxWarpRadius, "radius");
  checkAnchor(vol, anchor);
  // Each resample rounds the tip a little, so the surface drifts off the anchor the caller
  // carries from move to move (1.5 vu over 97 moves of a 200 vu drag): the move starts from the
  // surface point nearest the anchor (two Newton steps along the gradient, within the band).
  Vec3 from = vol.towardSurface(anchor, 2);
  // The move starts from the side of the tip that faces it: the surface point along the move's
  // direction from the tip's inside, the plateau's radius under `from`. At a turn of the path
  // the tip is then pulled out of its side, a tentacle along its own axis again, instead of
  // dragged sideways: that sheared the bend into a sheet thinner than a voxel, which tore (a
  // path of 90 degree turns in 4 vu moves left the tentacle in 4 pieces).
  const Vec3 d = target - from;
  const Vec3 g = vol.gradient(from);
  if (length(target - from) > 0 && length(g) > 0.5 && std::fabs(vol.sample(from)) < vol.band()) {
    const Vec3 dir = normalized(target - from);
    const Vec3 inside = from - normalized(g) * (kPlateau * radius);
    if (vol.sample(inside) < 0) {
      double lo = 0, hi = -1;
      for (double t = 0.5; t <= radius; t += 0.5)
        if (vol.sample(inside + dir * t) >= 0) {
          hi = t;
          break;
        } else {
          lo = t;
        }
      if (hi > 0) {
        for (int i = 0; i < 20; ++i) {
          const double mid = 0.5 * (lo + hi);
          (vol.sample(inside + dir * mid) < 0 ? lo : hi) = mid;
        }
        from = inside + dir * hi;
      }
    }
  }
  checkAnchor(vol, from);
  // The plateau's ball sinks into the tip, up to its own radius, so that from is on its front:
  // the ball then lies in the clay, and the clay in front of it lags behind (the falloff is
  // below 1 there) until it lies on the ball. The tip becomes the ball's front half, a round
  // cap that keeps the tentacle's thickness. With the ball's centre on the surface (before
  // 2026-11-30) the plateau carried the clay it first held, a flat cap, whole at every move, and
  // the clay just beyond its edge lagged more at every move: the rim sharpened with each move
  // (radius of curvature about 2 vu / moves) and the 200 vu tentacle's tip read gradient error
  // 0.19-0.22 (tests/engine/level_set/test_warp.cpp). The ball sinks only as far as the clay
  // clears the support's side: a ball sunk into the body, or into the tentacle's side at a
  // turn of the path, carried a slab of it sideways, sheared against the clay behind. A sunk
  // ball is as wide as the tip (tipRadius()): clay inside the ball never moves against it, so
  // a tip narrower than the plateau kept its flat cap in the ball, and read gradient error
  // 0.120 there after the 200 vu path (0.099 with the ball fitted).
  double ball = kPlateau * radius, share = 0;
  if (length(d) > 0) {
    const Vec3 along = normalized(d);
    const Vec3 sunk = from - along * ball;
    share = sinkShare(vol, sunk, along, radius);
    if (share > 0) {
      ball = std::max(kLeastBall * ball, tipRadius(vol, sunk, along, ball));
      from = from - along * (ball * share);
    }
  }
  // While the ball sinks only in part, the tentacle is young (as in its first moves out of a
  // body), and its foot is still being drawn: the move's support is then wider than the
  // radius, up to half again as the share falls, the ball's size kept, so that the falloff's
  // outer part reaches down the stub and draws the fold where it leaves the body into a broad
  // fillet. With the brush's support the moves' falloff stopped at the same ring on the body,
  // move after move, and the stub rose from it as a wall: a fold whose radius of curvature was
  // about a voxel, where the exact field of that shape read gradient error 0.126 and ours 0.129
  // after the 200 vu path (tests/engine/level_set/test_warp.cpp). The widening fades as the
  // ball sinks: half again the radius at every partial share fed itself (the wider flank kept
  // the ring of sinkShare() in the clay, the share partial), a 70 vu helix in moves of 1 vu
  // widened 64 of its 70 moves and cost 54% more instructions (fading: 3%). A move before the
  // ball sinks at all, off a body, keeps the brush's support, the ring the browser shows: a
  // wider support there draws the fillet as well, but costs every such move 13-19% more
  // (1.09-1.125 radii). Within the brush's support, other falloffs ((1 - u^a)^b) or other balls
  // left the exact field's fold at 0.086-0.143 (docs/benchmark-log.md, Warps).
  const double support =
      share > 0 && share < 1 ? std::min(radius * (1 + kYoungWidening * (1 - share)), snakeHookSupportBound(radius)) : radius;
  return grabVelocity(from, d, radius, ball, support);
}

}  // namespace

struct WarpMap::Field {
  Velocity v;
};

Vec3 WarpMap::forward(Vec3 p) const { return field_->v.flow(p, kWarpMapRefinement * field_->v.substeps(), 1); }

Vec3 WarpMap::inverse(Vec3 p) const { return field_->v.flow(p, kWarpMapRefinement * field_->v.substeps(), -1); }

WarpMap grabMap(Vec3 anchor, Vec3 d, double radius) {
  return WarpMap(std::make_shared<const WarpMap::Field>(WarpMap::Field{grabVelocity(anchor, d, radius, 0, radius)}));
}

WarpMap snakeHookMap(const Volume& vol, Vec3 anchor, Vec3 target, double radius) {
  return WarpMap(std::make_shared<const WarpMap::Field>(WarpMap::Field{snakeHookVelocity(vol, anchor, target, radius)}));
}

Edit grab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  return applyWarp(vol, base, grabVelocity(anchor, d, radius, 0, radius), pool);
}

Edit snakeHook(Volume& vol, Vec3 anchor, Vec3 target, double radius, ThreadPool& pool) {
  const Velocity v = snakeHookVelocity(vol, anchor, target, radius);
  // vol is its own base: applyWarp reads it before it writes the result.
  return applyWarp(vol, vol, v, pool);
}

Edit elasticGrab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius, double volume, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  requireRange(radius, kMinWarpRadius, kMaxWarpRadius / kElasticCutoff, "radius");
  requireRange(volume, 0, 0.5, "volume");
  if (!isFinite(d)) throw EngineError(ErrorKind::InvalidArgument, "d", "must be three finite numbers");
  if (!(length(d) <= kMaxElasticTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "d", "must be at most 2 radii long");
  Velocity v;
  v.kind = Velocity::Kind::Elastic;
  v.anchor = anchor;
  v.eps = radius;
  v.nu = volume;
  v.setSupport(kElasticCutoff * radius, kPlateau);
  // The load that moves the centre by d, before the flow's search.
  v.load = d * elasticLoadPerTravel(radius, volume);
  v.seg = d;
  landAnchor(v, anchor, d);
  return applyWarp(vol, base, v, pool);
}

Edit twist(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double angle, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  const Vec3 n = unitAxis(axis);
  requireRange(angle, -2 * std::numbers::pi, 2 * std::numbers::pi, "angle");
  Velocity v = affine(anchor, radius);
  // angle * [n]x: the cross product n x r.
  const double m[3][3] = {{0, -n.z, n.y}, {n.z, 0, -n.x}, {-n.y, n.x, 0}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.A[i][j] = angle * m[i][j];
  v.affineBound = twistSlopeBound(angle);
  return applyWarp(vol, base, v, pool);
}

Edit localScale(Volume& vol, const Volume& base, Vec3 anchor, double factor, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  requireRange(factor, 0.25, 4, "factor");
  Velocity v = affine(anchor, radius);
  for (int i = 0; i < 3; ++i) v.A[i][i] = std::log(factor);
  v.affineBound = localScaleSlopeBound(factor);
  return applyWarp(vol, base, v, pool);
}

Edit pinch(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double amount, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  const Vec3 n = unitAxis(axis);
  requireRange(amount, -1, 1, "amount");
  Velocity v = affine(anchor, radius);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.A[i][j] = -amount * ((i == j ? 1 : 0) - n[i] * n[j]);
  v.affineBound = pinchSlopeBound(amount);
  return applyWarp(vol, base, v, pool);
}

Edit pinchAlong(Volume& vol, Vec3 from, Vec3 to, Vec3 normal, double amount, double radius, ThreadPool& pool) {
  checkAnchor(vol, from);
  if (!isFinite(to)) throw EngineError(ErrorKind::InvalidArgument, "to", "must be three finite numbers");
  checkRadius(radius);
  requireRange(amount, -1, 1, "amount");
  if (!isFinite(normal) || !(length(normal) > 0))
    throw EngineError(ErrorKind::InvalidArgument, "normal", "must be a finite non-zero vector");
  const Vec3 d = to - from;
  if (!(length(d) <= kMaxWarpTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "to", "must be at most 8 radii from `from`");
  const Vec3 across = cross(normalized(normal), d);
  // A path along the normal has no side to draw in: nothing moves (as for a path of length 0).
  Velocity v;
  v.kind = Velocity::Kind::PathPinch;
  v.anchor = from;
  v.radius = radius;
  v.amount = amount;
  if (length(across) > 1e-9 * length(d)) {
    v.seg = d;
    v.segLength2 = dot(d, d);
    v.across = normalized(across);
    v.scale = amount / (kPathPinchPass * radius);
  }
  // vol is its own base: applyWarp reads it before it writes the result.
  return applyWarp(vol, vol, v, pool);
}

double grabSlopeBound(double travel, double radius) { return capsuleSlope(travel, radius, 0); }

double snakeHookSupportBound(double radius) { return std::min(radius * (1 + kYoungWidening), kMaxWarpRadius); }

// The widest plateau a move has: a sunk ball fitted to a narrower tip has a wider outer part,
// and a smaller bound.
double snakeHookSlopeBound(double travel, double radius) { return capsuleSlope(travel, radius, kPlateau); }

double elasticGrabSlopeBound(double travel, double radius, double volume) {
  return elasticSlope(travel * elasticLoadPerTravel(radius, volume), radius);
}

// |angle [axis]x| = sqrt 2 |angle|, |ln(factor) I| = sqrt 3 |ln factor|, |amount (I - axis axis^T)|
// = sqrt 2 |amount| (Frobenius norms, axis a unit vector).
double twistSlopeBound(double angle) { return affineSlope(std::numbers::sqrt2 * std::fabs(angle)); }

double localScaleSlopeBound(double factor) { return affineSlope(std::numbers::sqrt3 * std::fabs(std::log(factor))); }

double pinchSlopeBound(double amount) { return affineSlope(std::numbers::sqrt2 * std::fabs(amount)); }

// v = -scale I s across, scale = amount / (kPathPinchPass radius): |grad (I s)| <= I + |s| |grad I|,
// |s| <= radius. I <= min(L, 16 radius / 15) (its value on a long path's line), |dI/da| <=
// min(1, L max |K'|) with max |K'| = kQuarticMaxSlope / radius, and the part of grad I across the
// line, (2 h / radius^2) |G(u1) - G(u0)|, is at most min(kQuarticMaxSlope L / radius, sqrt 3)
// (G' in [0, 2c] on the chord, h c <= 0.385 radius, h c^(3/2) <= 0.325 radius).
double pinchAlongSlopeBound(double travel, double amount, double radius) {
  const double L = travel;
  return std::fabs(amount / (kPathPinchPass * radius)) *
         (std::min(L, 16 * radius / 15) + std::min(radius, kQuarticMaxSlope * L) +
          std::min(kQuarticMaxSlope * L, std::numbers::sqrt3 * radius));
}


}  // namespace marzipan
