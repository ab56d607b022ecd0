// Deformative tools by the level-set method (docs/method.md §3): phi_t + F |grad phi| = 0,
// followed after every application by keep / reset / fast-marching redistance.
//
// Local tools act inside a region of interest (ROI), the cube of half side `radius` around
// `center`, with the scaling-windowing speed F = s * W(q) * F0, W = prod_a (1 - t_a^2)^2,
// t_a = |q_a - c_a| / radius, evaluated at each voxel's foot point q = p - d grad d (the
// velocity extension: F is constant along normals, so phi - t F stays a distance field).
// W is 0 on the ROI boundary, so the surface moves only inside the ROI; the band voxels
// nearer than band + 1 vu to the ROI (nearer than band to the cells its voxels touch) are
// redistanced too where they may have changed, so that after every application the whole band
// is a distance field to the new surface. The returned Edit's region is the ROI grown by those
// voxels (clipped to the domain); nothing beyond it changes.
//
// Global tools use W = 1 over the whole volume. All tools: sign and units as in volume.hpp;
// the volume is modified in place and the returned Edit holds the replaced bricks; invalid
// parameters throw EngineError before anything changes. Results do not depend on the pool's
// thread count. Progress (progress.hpp): the calling thread's Progress is checked throughout
// (a local tool every few milliseconds; a cancelled one throws Cancelled and changes nothing)
// and advanced by one unit per local call, one per pass of a global one.
//
// Implemented in level_set/, a file per concern (its README.md maps them and says where a new
// tool goes).
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <utility>

#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"
#include "protocol/cpp/values.hpp"  // BrushParams

namespace marzipan {

// F0 = 1. One application moves the surface outward (add) or inward (remove) by `strength`
// vu at the tool centre, less towards the ROI boundary. Two upwind (Godunov, second-order
// ENO) steps of dt * |F| <= 0.5 vu each.
Edit addBlob(Volume& vol, const BrushParams& p, ThreadPool& pool = ThreadPool::serial());
Edit removeBlob(Volume& vol, const BrushParams& p, ThreadPool& pool = ThreadPool::serial());

// F0 = -mean curvature, with the fast curvature of a distance field: phi += dt * s * W * L(phi),
// L the 7-point Laplacian (= sum of principal curvatures). One application is one explicit
// step of dt = strength / 6 (the stability limit at strength 1).
Edit smooth(Volume& vol, const BrushParams& p, ThreadPool& pool = ThreadPool::serial());
// Negative smoothing: the same step backwards in time. Curvature is limited to |L| <= 1 per
// voxel so that noise cannot blow up; one application moves the surface <= strength/6 vu.
Edit sharpen(Volume& vol, const BrushParams& p, ThreadPool& pool = ThreadPool::serial());

// --- strokes: a swept brush --------------------------------------------------------------
// One application of a brush over several dabs at once: at each band voxel the speed scale is
// the largest weight * W over the dabs whose ROI holds it (a voxel outside every ROI does not
// move), evolved once and redistanced once over the union of the ROIs (grown by the band as
// above). A stroke that remembers what it applied passes its earlier dabs as `memory`: each
// voxel then moves only by the excess of this application's window over the largest earlier
// one, so a stroke moves each point of the surface by its strongest dab, however its dabs were
// grouped into applications. An empty memory lets every application add (build-up). Only the
// voxels where the excess is above 0 move, and only the band around them (within band + 1 vu
// of the cells they touch) is redistanced: elsewhere every voxel keeps its bits, and a group of
// dabs with nothing left to add changes nothing at all.
//
// A stroke with a height H (add and remove blob, inflate and clay) moves each point of the surface by H
// times that excess window, so a stroke with memory raises (lowers) the surface under a dab's
// centre by H, however its dabs were grouped. H may be several vu, more than the band is wide:
// the application runs in ceil(H * largest excess) sub-steps of at most 1 vu, each evolved and
// redistanced like one application, on one gathered grid. For the height to come out right the
// window must not shrink as the surface rises through it, so with a height each dab's window is
// read at the foot point q moved back along the dab's normal n (StrokeDab::normal) by (q - c).n
// clamped to [0, H] (add; [-H, 0] remove), the part of q's offset that the stroke's own motion
// may have put there: a point the stroke moved reads the window of where it started, and the
// window is constant along n over the height (a flank of a ridge reads its own distance from
// the ridge's line, not a shorter one). The surface moves as if carried along n (speed times
// n . its own normal, 0 where it faces away): then the moves of several applications add up
// exactly, in whatever pieces they come. A dab without a normal reads each voxel's own n, and
// then q moves back by all of (q - c).n, unclamped: q projected along n onto the plane through c,
// which a point moving along its own normal keeps (a ridge's flanks tilt n as it rises, so the
// pieces add up less exactly than along one normal: test_tools.cpp, inflate). The redistances of a stroke with a height do not
// normalize the kept voxels (that crept a crest outward message by message). Without a height, add and
// remove move the surface strength vu per application as before (bit for bit).
//
// The surface tools a sculptor knows by other names are these motions with rules of their own:
// - Inflate: every point moves outward along its own normal. Without a height that is what add
//   blob does (advection moves each point along its own normal), bit for bit; with a height each
//   dab's normal must be zero, so the window is anchored along each voxel's own normal.
// - Clay: add blob with a height under the palette's name: every point rises along the dab's
//   normal, which the caller sets to the stroke's average normal at its start (a clay dab with
//   a height must have one; without a height it is add blob, bit for bit).
// - Flatten: the surface moves towards StrokeSettings::plane, the plane fitted (fitBrushPlane)
//   when the stroke began: F0 = -h (n . m) at the foot point, h its signed distance to the plane
//   clamped to [-1, 1] vu (m the plane's unit normal), n the voxel's normal. One application
//   moves a point within 1 vu of the plane s * W of its way there along m ((n . m)^2 <= 1: never
//   past it), one farther by s * W (n . m) vu towards it, as add blob would. Contrast is its
//   inverse, away from the plane. With a memory a point near the plane moves by the excess
//   window's share of what is left, so a stroke sent in pieces flattens a little less there
//   than in one (test_tools.cpp).
// - Crease: remove blob with a window that falls to 0 at radius / 2.5 (tools.cpp), inside the
//   same ROI: as deep under the stroke, its groove is 2.5 times narrower at every depth, so its
//   flanks are 2.5 times steeper and it pinches to a sharp line as it sinks. Memory, pressure
//   and grouping are remove blob's.
enum class Brush { AddBlob, RemoveBlob, Smooth, Sharpen, Inflate, Clay, Flatten, Contrast, Crease };

// Whether the brush moves towards (away from) StrokeSettings::plane, which it then needs:
// flatten and contrast.
inline bool brushUsesPlane(Brush tool) { return tool == Brush::Flatten || tool == Brush::Contrast; }

// A plane: the points x with (x - point) . normal = 0; normal a unit vector.
struct Plane {
  Vec3 point, normal;
};
// The plane flatten and contrast move towards (from): the area-weighted centre and normal of
// the surface points of vol within `radius` of `center` (each band voxel's foot point, weighted
// by the hat 1 - |d| of its distance d, the surface's area per voxel). The caller fits it once, on
// the stroke's starting volume. Throws EngineError "center" where no surface lies within the
// radius, "radius" for one out of StrokeSettings' range.
Plane fitBrushPlane(const Volume& vol, Vec3 center, double radius);

struct StrokeSettings {
  StrokeSettings() = default;
  StrokeSettings(Brush t, double r, double s, std::optional<double> h = std::nullopt)
      : tool(t), radius(r), strength(s), height(h) {}

  Brush tool = Brush::AddBlob;
  double radius = 8;    // as BrushParams::radius
  double strength = 1;  // as BrushParams::strength; unused by add / remove blob with a height
  // vu, in (0, min(radius * kMaxStrokeHeightPerRadius, kMaxStrokeHeight)] (values.hpp); add
  // and remove blob, inflate and clay only.
  std::optional<double> height;
  // Flatten and contrast only, and they need one: finite, its normal a unit vector.
  std::optional<Plane> plane;
};

struct StrokeDab {
  StrokeDab() = default;
  StrokeDab(Vec3 c, double w = 1, Vec3 n = {}) : center(c), weight(w), normal(n) {}

  Vec3 center;        // vu; the dab's ROI must meet the domain
  double weight = 1;  // in (0, 1]: scales the dab's window (a pen's pressure)
  // A stroke with a height only: the unit outward normal of the surface at the centre as it was
  // when the stroke began, the direction the window is anchored along; zero: each voxel's own
  // (inflate's only choice; clay's must be a unit vector).
  Vec3 normal;
};

// Throws EngineError (field "radius", "strength", "height" or "plane") for settings applyStroke
// would refuse whatever its dabs.
void checkStrokeSettings(const StrokeSettings& st);
// Throws EngineError (field "center", "weight", "normal", "radius", "strength" or "height") for a dab that
// applyStroke would refuse; the volume is not read beyond its domain.
void checkStrokeDab(const Volume& vol, const StrokeSettings& st, const StrokeDab& dab);
// Applies `dabs` as one application (nothing when empty). Every dab is checked before
// anything changes. With one dab and no memory it is the brush tool above, bit for bit.
Edit applyStroke(Volume& vol, const StrokeSettings& st, std::span<const StrokeDab> dabs,
                 std::span<const StrokeDab> memory, ThreadPool& pool = ThreadPool::serial());

// Whole-volume mean curvature flow: `iterations` applications (each redistanced) of
// dt = strength / 6. A sphere of radius R0 follows R^2 = R0^2 - 4 t, t = iterations * dt.
Edit meanCurvatureFlow(Volume& vol, int iterations, double strength = 1,
                       ThreadPool& pool = ThreadPool::serial());

// Euclidean morphology with a sphere of radius k vu, as constant-speed level-set motion in
// applications of at most 1 vu. k in [0.001, 64].
Edit dilate(Volume& vol, double k, ThreadPool& pool = ThreadPool::serial());
Edit erode(Volume& vol, double k, ThreadPool& pool = ThreadPool::serial());
// open = erode then dilate (removes structure thinner than 2r); close = dilate then erode
// (fills gaps narrower than 2r).
Edit openSolid(Volume& vol, double r, ThreadPool& pool = ThreadPool::serial());
Edit closeSolid(Volume& vol, double r, ThreadPool& pool = ThreadPool::serial());

// Tests only: one whole-volume application of constant-speed advection that moves the surface
// `distance` vu (outward when positive) in `substeps` equal sub-steps, where dilate and erode
// take two per vu. |distance| / substeps in (0, 0.5] (the upwind scheme's CFL bound), substeps
// in [1, 64].
Edit advectInSubsteps(Volume& vol, double distance, int substeps, ThreadPool& pool = ThreadPool::serial());

// --- warps (level_set/warp*.cpp, level_set/README.md) --------------------------------------------
// Warp tools (docs/method.md §3, Warps): grab, elastic grab, snake hook, twist, local scale,
// pinch, pinch along a path. Sign and units as in volume.hpp (vu; d < 0 inside).
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
// Channels (channels.hpp): on a painted volume a voxel takes the colour of the voxel nearest
// X(x) (the colour moves with the clay) and keeps its own mask weight w; it moves by
// (1 - w / 255) of what it would (its distance where the result is written, Volume::diff,
// against base). A voxel whose clay comes through a voxel of weight 255 on its path from X(x)
// keeps base's distance and colour: under a full mask nothing changes, bit for bit.
//
// All calls: invalid parameters throw EngineError before anything changes; the calling thread's
// Progress (progress.hpp) is checked per slice (a cancelled call throws Cancelled and changes
// nothing) and advanced by one unit per call; results do not depend on the pool's threads.


// radius (vu) of every warp: in [kMinWarpRadius, kMaxWarpRadius] (a snake hook's from
// kMinSnakeHookRadius).
inline constexpr double kMinWarpRadius = 1;
inline constexpr double kMaxWarpRadius = 64;
// A snake hook's radius is at least this (the registry's snake_radius): its tentacle is about
// half the radius thick, and the grid loses a thinner one. Measured 2026-11-30 with the
// resample's cubic read next to the zero set (level_set/warp_reads.hpp): at radius 4 the tip held on
// every path tried, 30 and 70 vu in moves of 1 and 2 vu; at radius 3 it was lost after 13-59
// moves of a 70 vu drag (docs/method.md §3, Warps).
inline constexpr double kMinSnakeHookRadius = 4;
// A grab's |d| is at most this many radii (the work grows with |d|^2 * radius).
inline constexpr double kMaxWarpTravelPerRadius = 8;
// The largest |grad v| * dt of one integration sub-step.
inline constexpr double kWarpStretchPerStep = 0.25;

// Grab: moves `anchor` (a point on the surface of base, picked by the caller) by d. The velocity
// is d * W(rho / radius), W(t) = 1 - (6t^5 - 15t^4 + 10t^3) for t < 1 (flat at both ends: no tip
// at the centre, no fold at the rim; level_set/warp_fields.hpp, Falloff), rho the distance to the segment from
// anchor to anchor + d: the anchor travels along that segment at speed d and lands on
// anchor + d (checked; the velocity would be scaled by a 1-D search if it did not land within
// kWarpAnchorTolerance). A point beside the anchor at distance rho moves by W(rho / radius) d,
// the usual grab falloff. The changed region is the capsule of radius `radius` around the
// segment. Grabbing by -d from anchor + d integrates exactly the reverse flow.
inline constexpr double kWarpAnchorTolerance = 0.25;
Edit grab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius,
          ThreadPool& pool = ThreadPool::serial());

// Snake hook: one small move of a path-dependent stroke: grab of vol itself (its own base) by
// d = target - a, a the surface point nearest the current anchor (within the band: the
// caller's anchor, carried from move to move, drifts off the rounded tip), with a falloff that
// is 1 up to half the radius (the tip moves as a whole and keeps its thickness). The grab
// starts from the side of the tip that faces d: the surface point along d from half a radius
// under a (a itself when the move is along the tip's normal), so that at a turn of the path
// the tip is pulled out of its side, not sheared sideways; the plateau's ball sinks behind that
// point, up to its radius where the tip is thinner than the support, so that the tip is the
// ball's round front (level_set/warp_tools.cpp, snakeHookVelocity). The caller then takes target as the
// next anchor. A drag is the composition of its moves, so a long one pulls out a tentacle
// along the pointer's path. The changed region is the capsule of the move's support around
// the segment: `radius`, but while the ball sinks only in part (a young tentacle, whose foot is
// still being drawn) up to snakeHookSupportBound(radius).
Edit snakeHook(Volume& vol, Vec3 anchor, Vec3 target, double radius, ThreadPool& pool = ThreadPool::serial());
// The widest support a snake hook move of brush radius `radius` has (vu): half again the
// radius, at most kMaxWarpRadius. A caller sizing a move's work before it runs reads it here.
double snakeHookSupportBound(double radius);

// The map of one grab call or one snake hook move, for exact references (tests): the same
// velocity, scaled as the call scales it, as a map of points. forward(p) is where the flow
// carries the clay at p, inverse(p) where the clay at p comes from, each integrated with
// kWarpMapRefinement times the call's sub-steps (the call itself integrates the inverse with
// its own sub-steps). grabMap checks its parameters as grab does; snakeHookMap reads vol as
// snakeHook(vol, anchor, target, radius) would before moving it.
inline constexpr int kWarpMapRefinement = 16;
class WarpMap {
 public:
  struct Field;
  explicit WarpMap(std::shared_ptr<const Field> field) : field_(std::move(field)) {}
  Vec3 forward(Vec3 p) const;
  Vec3 inverse(Vec3 p) const;

 private:
  std::shared_ptr<const Field> field_;
};
WarpMap grabMap(Vec3 anchor, Vec3 d, double radius);
WarpMap snakeHookMap(const Volume& vol, Vec3 anchor, Vec3 target, double radius);

// Elastic grab: the anchor (a surface point) moved by d under a bi-scale regularized Kelvinlet
// (de Goes & James 2017; epsilons `radius` and 2 radius, Poisson ratio `volume` in [0, 0.5],
// 0.5 keeping the volume for small motions), cut off by a falloff that is 1 up to half of
// kElasticCutoff radii and 0 at kElasticCutoff radii, where the bi-scale field has fallen to a
// few percent: the changed region is that ball. The load is scaled by a 1-D search until the
// anchor lands on anchor + d within kWarpAnchorTolerance; radius in [1, kMaxWarpRadius /
// kElasticCutoff], |d| <= kMaxElasticTravelPerRadius radii.
inline constexpr double kElasticCutoff = 3;
inline constexpr double kMaxElasticTravelPerRadius = 2;
Edit elasticGrab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius, double volume,
                 ThreadPool& pool = ThreadPool::serial());

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

// Pinch along a path: one move of a path-dependent stroke (vol is its own base, as for
// snakeHook), the brush drawn from `from` to `to` along the surface, whose normal there is
// `normal` (any length, either sign). The surface on both sides is drawn towards the plane
// through the path along the normal, across it: with b = unit(normal x (to - from)) and
// s = b . (x - from) the signed distance to that plane,
//   v(x) = -amount / (16/15 radius) * I(x) * s * b,  I(x) = integral over the points p of the
//   segment of W(|x - p| / radius) (vu), W(t) = (1 - t^2)^2 for t < 1,
// which is the sum over the segment of a pinch dab's rate per vu of travel. A point that a long
// straight stroke passes (its segments' I add up to 16/15 radius on the path's line) is drawn
// towards the plane by the factor exp(-amount), by exp(-amount c^(5/2)) at the distance
// h = radius sqrt(1 - c) from the line, and how finely the stroke is cut into moves changes
// that only by the moves' non-commuting (tests/engine/level_set/test_warp.cpp says how much).
// amount in [-1, 1] (negative spreads), |to - from| at most kMaxWarpTravelPerRadius radii, from
// in the volume. The changed region is the capsule of `radius` around the segment; a path of
// length 0, or along the normal, moves nothing.
Edit pinchAlong(Volume& vol, Vec3 from, Vec3 to, Vec3 normal, double amount, double radius,
                ThreadPool& pool = ThreadPool::serial());

// Upper bounds of |grad v| of the warps' velocity fields, from the arguments of the call of the
// same name: a call integrates its flow in ceil(bound / kWarpStretchPerStep) sub-steps (the
// engine's own use), and a caller estimating a call's work reads them here. travel is the
// move's length: |d| (snake hook: |target - anchor|, pinch along: |to - from|). Grab, snake
// hook and elastic grab scale their field by the factor that lands the anchor on its target
// (a 1-D search from 1, kWarpAnchorTolerance): these are their bounds at factor 1, the call's
// are these times that factor.
double grabSlopeBound(double travel, double radius);
double snakeHookSlopeBound(double travel, double radius);
double elasticGrabSlopeBound(double travel, double radius, double volume);
double twistSlopeBound(double angle);
double localScaleSlopeBound(double factor);
double pinchSlopeBound(double amount);
double pinchAlongSlopeBound(double travel, double amount, double radius);

}  // namespace marzipan
