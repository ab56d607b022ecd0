// Warp tools (docs/method.md §3, Warps): grab, snake hook, twist, local scale, pinch. Sign and units
// as in volume.hpp (vu; d < 0 inside).
//
// A warp moves the solid by the flow of a stationary velocity field v for unit time. The new
// field is the old one read back through the inverse map: phi1(x) = phi0(X(x)), X(x) the point
// the flow carries to x, found by integrating -v from x (midpoint rule, enough sub-steps that
// |grad v| * dt <= kWarpStretchPerStep, so the discrete map stays a bijection: the flow of a
// smooth field never folds, however far it carries a point). phi0 is read by trilinear
// interpolation of its voxels: it never overshoots (no new zero crossings, no value past
// +-band), and past the band it gives +-band with phi0's sign, which is all the zero set needs.
// Higher-order interpolation would be smoother but the redistance that follows resets the
// slope anyway, and an overshooting stencil could make sign flips across thin parts. The
// voxels whose value changed, and the band within band + 1 vu of them, are then redistanced,
// so the whole band is a distance field again. v is zero outside a bounded support, and the
// flow maps the support onto itself: nothing outside it changes.
//
// The base volume: a warp stroke deforms the solid as it was when the stroke began (the
// caller keeps that version; a Volume copy is cheap). Each call writes base warped by the
// call's parameters into vol, and puts back base's values wherever an earlier call of the same
// stroke changed vol beyond this call's region: vol must be base or base changed by earlier
// calls of the stroke. The result depends only on base and the call's parameters, so a grab
// stroke ends the same, bit for bit, however its messages were grouped. Each call returns the
// Edit that takes vol (as it was) to the result.
//
// All calls: invalid parameters throw EngineError before anything changes; the calling thread's
// Progress (progress.hpp) is checked per slice (a cancelled call throws Cancelled and changes
// nothing) and advanced by one unit per call; results do not depend on the pool's threads.
#pragma once

#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

// radius (vu) of every warp: in [kMinWarpRadius, kMaxWarpRadius].
inline constexpr double kMinWarpRadius = 1;
inline constexpr double kMaxWarpRadius = 64;
// A grab's |d| is at most this many radii (the work grows with |d|^2 * radius).
inline constexpr double kMaxWarpTravelPerRadius = 8;
// The largest |grad v| * dt of one integration sub-step.
inline constexpr double kWarpStretchPerStep = 0.25;

// Grab: moves `anchor` (a point on the surface of base, picked by the caller) by d. The velocity
// is d * W(rho / radius), W(t) = (1 - t^2)^2 for t < 1, rho the distance to the segment from
// anchor to anchor + d: the anchor travels along that segment at speed d and lands on
// anchor + d (checked; the velocity would be scaled by a 1-D search if it did not land within
// kWarpAnchorTolerance). A point beside the anchor at distance rho moves by W(rho / radius) d,
// the usual grab falloff. The changed region is the capsule of radius `radius` around the
// segment. Grabbing by -d from anchor + d integrates exactly the reverse flow.
inline constexpr double kWarpAnchorTolerance = 0.25;
Edit grab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius,
          ThreadPool& pool = ThreadPool::serial());

// Snake hook: one small move of a path-dependent stroke: grab of vol itself (its own base) from
// the current anchor to `target`, with a falloff that is 1 up to half the radius (the tip moves
// as a whole and keeps its thickness); the caller then takes target as the next anchor. A drag
// is the composition of its moves, so a long one pulls out a tentacle along the pointer's path.
Edit snakeHook(Volume& vol, Vec3 anchor, Vec3 target, double radius, ThreadPool& pool = ThreadPool::serial());

// Affine warps: v(x) = P(|x - anchor| / radius) * A (x - anchor), P = 1 up to half the radius
// and falling as (1 - u^2)^2 (u from 0 to 1 over the outer half) to 0 at the radius: inside
// the half radius the flow is exactly exp(A), a rotation, a scaling. The anchor stays put.
// twist: A = angle * [axis]x, rotates by `angle` (radians, |angle| <= 2 pi) about the line
// through anchor along axis (a unit vector, normalised here; e.g. the surface normal).
Edit twist(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double angle, double radius,
           ThreadPool& pool = ThreadPool::serial());
// local scale: A = ln(factor) I, factor in [0.25, 4].
Edit localScale(Volume& vol, const Volume& base, Vec3 anchor, double factor, double radius,
                ThreadPool& pool = ThreadPool::serial());
// pinch: A = -amount (I - axis axis^T): draws the surface toward the axis through the anchor
// (tangentially, for axis the normal) by the factor exp(-amount); amount in [-1, 1] (negative
// spreads).
Edit pinch(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double amount, double radius,
           ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
