// The one place where an operation object (protocol/cpp/ops.hpp) becomes an engine call.
// `marzipan batch` and the server both apply ops through here, so an op means the same thing
// offline and online. Conventions as in the engine: the volume is edited in place, the Edit
// holds the replaced bricks, and an EngineError (thrown before anything changes) propagates
// unchanged. The volume's revision is left to the caller, who owns the history.
#pragma once

#include <cstddef>
#include <optional>
#include <span>

#include "engine/edit.hpp"
#include "engine/level_set.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "protocol/cpp/ops.hpp"
#include "protocol/cpp/rpc.hpp"
// engineBrush (the engine's Brush of a surface-speed tool), applyMorph, applyGlobalSmooth:
// generated from the tool registry (protocol/registry/tools.json) at build time.
#include "service/engine_tools.generated.hpp"

namespace marzipan::service {

Edit applyOp(Volume& vol, const protocol::Op& op, ThreadPool& pool);

// The wire name of a paint stroke's tool (registry kind paint): "paint", or "mask" for both
// mask modes (erasing is mask's `erase`).
std::string_view paintToolName(PaintMode mode);
// The engine's settings of a paint or mask stroke.begin (p.paint set): mask with erase is
// MaskErase; the colour's bytes as they are.
PaintSettings paintSettingsOf(const protocol::StrokeBeginParams& p);

// What an op will cost before it runs, for the server's per-request budget and progress.
// voxels: voxels processed, an upper estimate that goes with the time it takes: a local
// tool's region (the worst place: clipped to the domain, grown by the band), or for a
// whole-volume op the domain's voxels times its passes (0 for a volume without stored
// bricks). Every kind runs at about the same rate per voxel so counted: measured 2026-11-24
// on this 2-core VM (brushes serial as the server runs them, the others on 2 threads), quiet:
// add_blob/smooth/sharpen radius 140 on 256^3 0.64-0.75 s (2.2-2.6e7 voxels/s), add_blob
// radius 300 on the 512^3 sphere 4.0-5.2 s (2.6-3.3e7), csg_add radius 120 on 256^3 0.61 s
// (2.5e7) and radius 250 on 512^3 4.3-4.7 s (2.9e7), a smoothing pass of the 192^3 pig
// 0.26 s (2.7e7); busy (load 10) about 1e7 voxels per second.
// passes: progress units (engine/progress.hpp): the chunked whole-volume passes it makes, or
// 1 for a local op (the engine counts its phases in fractions of it).
struct OpCost {
  double voxels = 0;
  double passes = 0;
};
OpCost estimateCost(const Volume& vol, const protocol::Op& op);
// The same for one brush dab of this radius and its mirror images (1 to 8).
double brushVoxels(const Volume& vol, double radius, int images = 1);
// The most remembered dabs of a stroke whose region may hold one voxel (an upper bound: their
// centres lie within the voxel's neighbourhood of cells of a grid of twice the reach).
std::size_t rememberedOverlap(std::span<const StrokeDab> memory, double reach);
// One dab of a stroke message, as brushVoxels, with the stroke's height sub-steps and its
// memory: where remembered dabs are weaker than the message's, each voxel the message moves
// scans every remembered dab whose region holds it (engine applyStroke), kRememberedDabVoxels
// voxels' worth each: measured 2026-11-29 on this 2-core VM (tests/service/test_apply_op.cpp),
// a radius-12 dab on 96^3 took 0.42 ms alone and 39 ms over 4096 weak remembered dabs, 0.0225
// voxel per remembered dab; 0.03 keeps the estimate above the time.
double strokeDabVoxels(const Volume& vol, double radius, int images, double substeps,
                       std::span<const StrokeDab> memory);
inline constexpr double kRememberedDabVoxels = 0.03;

// --- warp strokes (protocol/PROTOCOL.md, "Warp strokes") ------------------------------------
// What a warp stroke keeps between its messages. The stroke's first dab is the anchor, a point
// of the base's surface (the volume as the stroke began); every later dab is the pointer's point
// p, and D = strength * (p - anchor) the drag. Anchored tools warp the base by the last p only:
// grab and elastic grab by d = D, twist, scale and pinch by an amount from s = (D . u) / radius,
// u the unit direction (or unit(D) without one): twist by s * pi / 2 radians about the anchor's
// outward normal, scale by the factor 2^s, pinch by s / 2 towards the normal's line. Snake
// hook moves the current anchor to anchor + D, dab after dab, each move composed on the last.
// Pinch path's dabs are points on the surface, and there is no drag: each later dab p is a move
// of the engine's pinchAlong from the dab before to p (in pieces of at most
// kMaxWarpTravelPerRadius radii), its amount strength times p's pressure (1 when not given), the
// normal the volume's at p as the stroke has made it; a dab outside the volume is refused.
// Every value is clamped to the engine's limits (level_set.hpp, warps): |d| to
// kMaxWarpTravelPerRadius (elastic: kMaxElasticTravelPerRadius) radii, the angle to +-2 pi, the
// factor to [0.25, 4], the pinch to [-1, 1]; past them the surface stays where the limit left it.
// Pressure does not enter the others: the pointer's place is the drag. Units: vu and radians.
struct WarpStroke {
  protocol::WarpTool tool = protocol::WarpTool::Grab;
  double radius = 8, strength = 1;
  double volume = 0.5;            // elastic grab's Poisson-like ratio, in [0, 0.5]
  std::optional<Vec3> direction;  // twist, scale, pinch: finite, not zero, any length
  // Set by the first dab: the anchor (snake hook: the current one, moved by every dab) and the
  // base's outward unit normal there.
  std::optional<Vec3> anchor;
  Vec3 normal;
  // The last pointer point applied (anchored tools).
  std::optional<Vec3> pointer;
  // What the base already holds of the drag since a rebase (rebaseWarp): the grab's d, or the
  // affine warps' amount (twist: radians; scale: log2 of the factor; pinch: the amount).
  Vec3 heldD;
  double heldAmount = 0;
};

// The farthest a warp's anchor is taken as given from the base's surface (|distance| in vu).
inline constexpr double kMaxWarpAnchorDistance = 2;
// Newton steps that carry an anchor farther than that, but within the band, to the surface.
inline constexpr int kAnchorSnapSteps = 8;

// Checks a warp stroke's settings as the engine will (radius: the tool's range; volume,
// direction); throws EngineError naming the field.
void checkWarpSettings(const WarpStroke& w);
// Takes `at` as the anchor on `base` (w.anchor, w.normal). A point within
// kMaxWarpAnchorDistance of base's surface is taken as given; one farther but within the band
// (a client's pick on splats that another sculptor's edit has since moved) is taken at the
// surface point nearest it (Volume::towardSurface, within kWarpAnchorTolerance of the zero
// set). Throws EngineError (field "center") when it lies outside the domain, cannot be carried
// to the surface so, or where base's field has no slope to give a normal.
void setWarpAnchor(WarpStroke& w, const Volume& base, Vec3 at);
// One message's pointer points (the dabs after the anchor) on a stroke with its anchor set:
// anchored tools write base warped by the last point into vol (which must be base or base
// changed by this stroke's earlier calls, engine warps); snake hook moves the anchor through
// each point in turn on vol, pinch path along them (pressures: one per point, or none for 1).
// Returns the Edit from vol as it was, and sets w's pointer and
// anchor. A throw (EngineError, Cancelled) leaves w as it was and, for anchored tools, vol; a
// path's earlier moves of the message stay in vol: the caller puts vol back.
Edit applyWarpStroke(Volume& vol, const Volume& base, WarpStroke& w, std::span<const Vec3> points, ThreadPool& pool,
                     std::span<const double> pressures = {});
// The work of that call (OpCost units, as estimateCost: voxels processed; passes: its engine
// calls). `anchor` stands for w.anchor when that is not set yet (the message's first dab).
// A warp resamples the box of its support (grown by the band) and integrates the flow of each
// voxel near the zero set over |grad v| / kWarpStretchPerStep sub-steps, so its work goes with
// the box times (1 + kWarpStepVoxels * sub-steps): for a grab by d, |d|^2 * radius once d
// outgrows the radius. kWarpStepVoxels: marzipan-bench grab_message, 2026-11-29 10:44 UTC on
// this 2-core VM (load 6-7, three runs): a grab message of radius 20 on the 256^3 sphere, the
// pointer 20 / 60 vu from the anchor, took 12.9-16.1 / 26.5-44.9 ms (CPU 8.5-9.0 / 17.9-19.1),
// its box 2.6e5 / 5.7e5 voxels and 7 / 19 sub-steps: the box alone accounts for most of it since
// the flow runs on the segment's one coordinate; 0.05 puts the estimate at 3.5e5 / 1.1e6, the
// rate of the other tools (2.2-3.3e7 voxels/s quiet), and keeps the sub-steps' share for
// the affine and elastic warps, whose flow is integrated per sub-step.
OpCost warpStrokeCost(const Volume& vol, const WarpStroke& w, std::optional<Vec3> anchor, std::span<const Vec3> points,
                      std::span<const double> pressures = {});
inline constexpr double kWarpStepVoxels = 0.05;
// After a change of the volume that was not the stroke's (or at a snapshot): the stroke goes on
// from the volume as it is, which holds what it applied. Its base is then that volume (the
// caller's part); here what the drag had applied becomes held, so that the next message
// applies only the rest (grab: from the moved anchor). Idempotent.
void rebaseWarp(WarpStroke& w);

}  // namespace marzipan::service
