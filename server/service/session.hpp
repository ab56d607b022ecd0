// One sculpting session: a volume, its undo history, the revision clients see, and the open
// strokes. No sockets and no JSON: the network layer parses requests into these types and
// turns results and ServiceErrors into messages.
//
// Conventions:
// - Threading: a Session is not thread-safe. Every method, const ones included, must be called
//   from one thread at a time: the session's strand. Heavy work runs on the ThreadPool passed
//   in. Readers on other threads (renderers, splat extraction for slow clients, saving) take
//   snapshot() on the strand and then read that copy freely: bricks are copy-on-write, so the
//   copy costs O(tiles) and later edits never touch it.
// - Ownership: the Session owns its Volume and History; snapshots share bricks with it.
// - Revision: starts at the initial volume's revision() (a volume file keeps it) and goes up by
//   exactly one for every call that changes the field: apply, strokeDabs, undo, redo, load. A
//   call that changes no voxel (an op with no effect, a message whose rays all miss, undo with
//   nothing to undo) leaves it alone and says so (`changed`). The volume's own revision() is
//   kept equal to it, so a saved file carries it. undoMine and redoMine count like undo and redo.
// - Authors: apply, beginStroke and load take the StepAuthor their step is recorded with
//   (service/history.hpp); the time of a step is read from the session's clock (setClock).
// - Errors: every public method validates its input and throws ServiceError before changing
//   anything; engine errors are turned into ServiceError too. After a throw the field, the
//   history and the revision are exactly as before.
// - Units and signs are the engine's (server/engine/volume.hpp): vu, d < 0 inside.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "protocol/cpp/geometry.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/paint.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "protocol/cpp/ops.hpp"
#include "protocol/cpp/rpc.hpp"
#include "service/apply_op.hpp"
#include "service/history.hpp"

namespace marzipan::service {

// A refusal of the session model, with the JSON-RPC code of protocol/PROTOCOL.md it is answered
// with (protocol/cpp/rpc.hpp, the one list of codes): InvalidParams (a value is malformed or
// out of range; `field` names it), EngineRefused (the tool's region misses the volume's
// domain), NoSuchStroke (none with this id was begun, or it has ended: the message tells),
// LimitExceeded (too many open strokes, or a size over the engine's limits).
class ServiceError : public std::runtime_error {
 public:
  ServiceError(protocol::RpcCode code, std::string field, const std::string& message)
      : std::runtime_error(message), code_(code), field_(std::move(field)) {}
  protocol::RpcCode code() const { return code_; }
  // The offending parameter ("stroke", "dabs[3].ray.direction"), or empty.
  const std::string& field() const { return field_; }
  std::string message() const { return what(); }

 private:
  protocol::RpcCode code_;
  std::string field_;
};

struct Ray {
  Vec3 origin, direction;  // direction: finite, non-zero, any length
};

// The first point where the ray (t >= 0) meets the surface: the zero set of the volume's
// trilinear interpolant (Volume::sample, what the renderer draws), capped half a voxel beyond
// the domain like the renderer. An origin inside the solid is its own hit. nullopt when the ray
// misses, or when origin or direction are not finite or the direction is zero.
// Method: march from where the ray enters the domain (grown by one voxel) in steps of
// max(0.1, d/2) vu, then bisect the first step that ends at d <= 0 down to 1e-9 vu. A step of
// d/2 cannot pass over the surface where |grad d| <= 2 (any distance field); as in the
// renderer, a sheet thinner than 0.1 vu hit at a grazing angle can be missed.
std::optional<Vec3> pickSurface(const Volume& vol, Vec3 origin, Vec3 direction);

// Mirror images of a dab across the domain's centre planes: x mirrors p.x to (nx - 1) - p.x,
// the plane through the middle of the voxels (makeSolid centres its solids on it). Any
// combination; a dab at p applies at p and at each distinct image (p, x, y, xy, z, xz, yz,
// xyz), all in the same application as the message's other dabs.
struct Symmetry {
  bool x = false, y = false, z = false;
};
// A dab's distinct images under the symmetry (the dab first), its normal mirrored alike.
std::vector<StrokeDab> mirrorImages(const StrokeDab& dab, Symmetry s, Int3 dims);

struct Dab {
  Dab() = default;
  Dab(std::variant<Vec3, Ray> a, std::optional<double> p = std::nullopt, std::optional<Vec3> n = std::nullopt)
      : at(a), pressure(p), normal(n) {}

  std::variant<Vec3, Ray> at;       // a centre, or a pick ray (its first surface hit)
  std::optional<double> pressure;  // in [0, 1], scales the stroke's strength; 1 when absent; 0 = no dab
  // A stroke with a height: the starting surface's unit normal at the centre (StrokeDab::normal)
  // as recorded in the journal; absent: taken from the stroke's starting volume.
  std::optional<Vec3> normal;
};

using StrokeId = std::uint64_t;  // 0 is never a stroke

struct ApplyResult {
  std::uint64_t revision = 0;
  bool changed = false;  // false: no voxel changed, the revision is the same
  Box roi;               // voxels the call may have touched (clipped to the domain); empty if none
  // Bricks whose splats must be re-extracted (bricksAroundChanges): a splat delta. Ignore when
  // fullRefresh is set: the domain itself changed and clients need a full buffer.
  std::vector<Int3> bricks;
  bool fullRefresh = false;
  // strokeDabs only, one per dab in order: the centre used (before mirroring), or nullopt for
  // a ray that missed the surface (that dab did nothing). A centre dab reports its centre.
  std::vector<std::optional<Vec3>> hits;
  // strokeDabs only, one per dab: the normal it was anchored along (zero: none; a stroke
  // without a height, or a missed ray), for the journal.
  std::vector<Vec3> normals;
  // strokeDabs only: the stroke's plane once it has one (Session::beginStroke, "The stroke's
  // plane"), for the reply and the journal.
  std::optional<Plane> plane;
  std::size_t missed = 0;  // how many rays missed
  // A warp stroke's message that took the stroke's anchor: it changed the stroke even when it
  // changed no voxel (changed false), so the journal records it.
  bool anchored = false;
};

struct HistoryResult {
  std::uint64_t revision = 0;
  bool changed = false;  // false: nothing to undo / redo
  bool canUndo = false, canRedo = false;
  Box roi;                   // the step's region
  std::vector<Int3> bricks;  // bricks to re-extract, as in ApplyResult
  // The bricks the step put in place, as they are now: enough to redo this move on a copy of
  // the volume whose history is gone (the journal keeps them for replay after a snapshot).
  std::vector<std::pair<Int3, BrickRef>> restored;
  std::optional<StepInfo> step;      // the step moved (changed set)
  // undoMine/redoMine refused (changed false, nothing changed): the step that holds a brick of
  // the caller's step (its author and revision name it); step is then the caller's step.
  std::optional<StepInfo> conflict;
};

struct SessionStats {
  Measures measures;  // measures.digest is the digest in hex
  std::uint64_t revision = 0;
  std::uint64_t digest = 0;
  bool canUndo = false, canRedo = false;
  std::size_t undoSteps = 0, redoSteps = 0, historyBytes = 0;
  std::size_t openStrokes = 0;
  std::size_t memoryBytes = 0;  // the live volume's (Volume::memoryBytes)
};

class Session {
 public:
  static constexpr std::size_t kMaxOpenStrokes = 64;

  explicit Session(Volume initial, std::size_t historyBudgetBytes = History::kDefaultBudgetBytes);

  // One operation object (a brush dab, a CSG tool, global smoothing or morphology) as one
  // history step. Throws ServiceError (EngineRefused when its region misses the domain); any
  // other exception (Cancelled through the thread's Progress, engine/progress.hpp, or
  // std::bad_alloc) also leaves the session exactly as before.
  ApplyResult apply(const protocol::Op& op, ThreadPool& pool, const StepAuthor& by = {});

  // The first surface hit of a ray on the live volume, for `tool.apply` with a ray: the caller
  // sets the op's centre to it. Throws InvalidParams (field "ray.origin"/"ray.direction") for a
  // non-finite origin, a zero or non-finite direction, or an origin beyond +-1e6 vu.
  std::optional<Vec3> pick(const Ray& ray) const;

  // Opens a stroke of one brush tool. radius in [0.5, 1024] vu, strength in (0, 1].
  // accumulate: every message adds (build-up) instead of only what exceeds the stroke's
  // earlier dabs (see strokeDabs). height (add/remove blob, inflate, clay; not accumulating; vu
  // in (0, min(radius / 2, 64)]): the stroke moves the surface by at most this (engine
  // StrokeSettings), each dab anchored along the starting surface's normal at its centre (add
  // and remove blob), along each point's own normal (inflate) or along the stroke's normal
  // (clay: its plane's, below).
  // Its steps are recorded as by's. The stroke keeps the volume as it began (bricks shared).
  //
  // The stroke's plane: flatten and contrast move towards (away from) a plane, and clay with a
  // height along one normal, both of the surface as the stroke began. stroke.begin has no
  // centre, so the plane is fitted (engine fitBrushPlane: the area-weighted centre and normal of
  // the surface within the radius) on the stroke's starting volume around the first dab that
  // applies (a centre, or a ray's hit, with a pressure above 0), in the message that has it,
  // and kept for the rest of the stroke. A message whose first such dab has no surface within
  // the radius is refused (InvalidParams, field "dabs[i].center") and changes nothing. With
  // symmetry each mirror image moves towards the plane mirrored alike: flatten and contrast
  // apply the images of each mirror one after the other in the same message (each with its own
  // share of the memory), so near a mirror plane, where the images' regions meet, a point moves
  // by both rather than by the stronger (clay's images are one application, as add blob's).
  StrokeId beginStroke(protocol::BrushTool tool, double radius, double strength, Symmetry symmetry = {},
                       bool accumulate = false, const StepAuthor& by = {},
                       std::optional<double> height = std::nullopt);
  // One message of dabs is one application of the brush swept over them (engine applyStroke):
  // each point moves by the strongest dab over it (pressure scales a dab's window; mirror
  // images included), evolved and redistanced once. Rays are picked on the volume as it was
  // when the stroke began. Unless the stroke accumulates it remembers the dabs it applied (its
  // newest kMaxStrokeMemory images; not those of a message that changed nothing, which the
  // journal does not record), and a later message moves a point only by what exceeds
  // them, so the result does not depend on how the stroke's dabs were grouped into messages.
  // All dabs of one stroke fold into one history step, which stays open while it is the
  // newest step: any other change of the session (apply, undo, redo, load, another stroke's
  // dabs) closes it and the stroke's next dabs start a new step. A stroke with an author (its
  // person's own undo) goes on folding into its step across others' changes while nothing is
  // undone and no later step touched a brick its message changes (History::fold): one stroke
  // stays one step while other people sculpt elsewhere. The whole message is checked
  // before anything changes, so a throw changes nothing. One revision per call that changed
  // something.
  // A warp stroke's message (beginWarp; PROTOCOL.md, warp strokes): its first dab, while the
  // stroke has none, is the anchor (a centre, or a ray picked on the stroke's base; refused,
  // field "center", off the surface), every other dab a centre (a ray: refused); the volume
  // becomes the base warped by the stroke (apply_op.hpp, applyWarpStroke), folded into the
  // stroke's step as a brush's messages are. The base is the volume as the stroke began, or,
  // when something else changed the session since the stroke's last message, the volume as it
  // is then (rebaseWarp): a stroke never undoes others' changes. Pressure scales a pinch
  // path's moves; the other warps ignore it.
  ApplyResult strokeDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool);
  // Opens a warp stroke with w's settings (checkWarpSettings; InvalidParams naming the field).
  // A w whose anchor is set (re-announced after a snapshot, journal_records.hpp) goes on from
  // the volume as it is. Its steps are recorded as by's.
  StrokeId beginWarp(WarpStroke w, const StepAuthor& by = {});
  // Opens a paint or mask stroke (engine paintStroke, server/engine/paint.hpp; PROTOCOL.md,
  // paint and mask strokes): st's mode, colour, radius, strength and hardness (checkPaintSettings;
  // InvalidParams naming the field). Its messages are swept dabs as a brush's (strokeDabs: rays
  // picked on the volume as the stroke began, pressure, mirror images, the stroke's memory
  // unless it accumulates, one history step), each one application of paintStroke; they change
  // channels only. A dab whose region misses the domain is refused (EngineRefused, field
  // "dabs[i].center").
  StrokeId beginPaint(const PaintSettings& st, Symmetry symmetry = {}, bool accumulate = false, const StepAuthor& by = {});
  // The work of a warp stroke's message (warpStrokeCost), for the caller's budget; nullopt when
  // the stroke is no open warp stroke.
  std::optional<OpCost> warpCost(StrokeId id, const std::vector<Dab>& dabs) const;
  // Every open warp stroke goes on from the volume as it is (rebaseWarp), as the head records
  // of a new journal announce them: called when a snapshot was taken.
  void rebaseWarps();
  // Replaces what an open stroke remembers having applied (a journal replayed after a snapshot
  // that cut the stroke in two). Throws UnknownStroke / StrokeClosed.
  void setStrokeMemory(StrokeId id, std::vector<StrokeDab> applied);
  // Sets an open stroke's plane (its first message's, as the journal recorded it: replay after a
  // snapshot no longer has the starting volume it was fitted on). Throws UnknownStroke /
  // StrokeClosed, InvalidParams (field "plane") for a plane not finite or not of a unit normal,
  // or for a stroke of a tool without one.
  void setStrokePlane(StrokeId id, const Plane& plane);
  static constexpr std::size_t kMaxStrokeMemory = 4096;
  // Closes the stroke; its step can no longer grow. Throws UnknownStroke / StrokeClosed.
  void endStroke(StrokeId id);
  // Bytes of the brick buffers that open strokes' starting volumes hold and the live volume no
  // longer does (each buffer once): what open strokes keep alive. Reads every brick of each
  // stroke's start.
  std::size_t strokeHeldBytes() const;
  // Ends, as endStroke() does, every open stroke that had no message (beginStroke, strokeDabs)
  // for idleMs of the stroke clock (setStrokeClock), then the oldest open strokes until strokeHeldBytes() is
  // at most maxBytes. Returns the strokes ended, in that order. Cheap while an upper bound of
  // what the strokes hold (the bricks changed since each began) stays within maxBytes.
  std::vector<StrokeId> endStaleStrokes(std::size_t maxBytes, std::int64_t idleMs);

  HistoryResult undo();
  HistoryResult redo();
  // Undoes / redoes author's own newest step (History::undoOf/redoOf): changed with the same
  // result as undo()/redo(), or not changed with conflict set (refused: a later step of anyone
  // touched one of its bricks), or neither (the author has no step to move). An empty author
  // has no steps.
  HistoryResult undoMine(const std::string& author);
  HistoryResult redoMine(const std::string& author);
  // Puts these bricks in place as one change that cannot be undone (the history is cleared):
  // an undo or redo replayed from the journal after the step it moves was lost to a snapshot.
  // Throws InvalidParams for a brick outside the grid; a change of nothing still counts.
  HistoryResult restore(const std::vector<std::pair<Int3, BrickRef>>& bricks);

  // Replaces the field by `vol`'s (a `volume.load`). With the same dims, band and base colour it
  // is one undoable step holding only the bricks that differ; otherwise the domain changes, the
  // history is cleared (steps of another grid cannot be replayed) and fullRefresh is set.
  // Open strokes stay open (their next dab starts a new step) and start over from the loaded
  // volume: their rays pick on it, their normals are read on it. The revision goes up by one
  // (the file's own revision is ignored), even when the field is identical.
  ApplyResult load(Volume vol, const StepAuthor& by = {});

  // The steps in history order (History::list).
  std::vector<StepInfo> steps() const { return history_.list(); }
  // The newest undo step: after a change, the step it made or grew (its author and time go in
  // the journal record, journal_records.hpp stampRecord).
  std::optional<StepInfo> newestStep() const { return history_.newest(); }
  // The volume right after step `revision` with the later steps reverted (History::volumeAt),
  // or the current volume when revision is the session's; nullopt otherwise. The live volume is
  // not touched: bricks are shared copy-on-write. Reads and unpacks the later steps' bricks, on
  // the strand.
  std::optional<Volume> volumeAt(std::uint64_t revision) const;
  // The starting volume of a fork: the current volume (no revision) or volumeAt(revision); its
  // revision() is that revision, the new Session starts from it with an empty history. Throws
  // InvalidParams (field "revision") when the revision is neither current nor a step's.
  Volume forkVolume(std::optional<std::uint64_t> revision = std::nullopt) const;
  // The volume at `revision` as cheaply as it comes: the current one or the history's kept
  // version (History::keptAt) at once, else the Rebuild that builds it (History::rebuildAt), to
  // run off the strand and hand back to keep(). Throws InvalidParams as forkVolume.
  std::variant<Volume, Rebuild> versionAt(std::uint64_t revision) const;
  void keep(const Rebuild& r, const Volume& built) const { history_.keep(r, built); }

  // Where step times come from (ms since the Unix epoch); the system clock by default. Replay
  // sets the journal's times; tests a fixed clock.
  void setClock(std::function<std::int64_t()> nowMs);
  // Where the times of stroke messages come from (endStaleStrokes), in ms: a steady clock by
  // default; tests set their own. Not the step clock: replay sets that one to the journal's.
  void setStrokeClock(std::function<std::int64_t()> nowMs);

  // A copy of the current version for readers on other threads (see the conventions above).
  Volume snapshot() const { return volume_; }
  const Volume& volume() const { return volume_; }
  const History& history() const { return history_; }
  std::uint64_t revision() const { return revision_; }
  // digest(volume()), kept up to date brick by brick (engine/measures.hpp) instead of read: the
  // channels and a base colour other than the clay's count, an unpainted clay volume's digest is
  // its distances' alone.
  std::uint64_t digest() const {
    return digestFromTerms(volume_.dims(), volume_.band(), digestTerms_, volume_.baseColor());
  }
  bool canUndo() const { return history_.canUndo(); }
  bool canRedo() const { return history_.canRedo(); }
  std::size_t openStrokes() const { return strokes_.size(); }
  struct StrokeParams {
    protocol::BrushTool tool;
    double radius, strength;
    Symmetry symmetry;
    bool accumulate = false;
    // the dab images it applied, oldest first (flatten and contrast: the dabs before their mirror
    // images, each mirror's images being made again from them)
    std::vector<StrokeDab> memory;
    StepAuthor by{};
    std::optional<double> height{};
    std::optional<Plane> plane{};  // see beginStroke, "The stroke's plane"
    std::optional<WarpStroke> warp{};  // a warp stroke (tool, symmetry, accumulate, memory unused)
    std::optional<PaintSettings> paint{};  // a paint or mask stroke (tool and height unused)
  };
  // The open strokes and their parameters, by id.
  std::vector<std::pair<StrokeId, StrokeParams>> openStrokeList() const;
  // One open stroke's parameters without copying its memory (left empty); nullopt when the
  // stroke is not open. What a stroke.dabs message is checked against, on every message.
  std::optional<StrokeParams> strokeSettings(StrokeId id) const;
  // What an open stroke remembers having applied (empty when it is not open), valid until the
  // session's next change.
  std::span<const StrokeDab> strokeMemory(StrokeId id) const;

  // Measures of the live volume (reads every brick: on a large session compute measure() on a
  // snapshot off the strand and add counters(), as the hub's session.stats does).
  SessionStats stats() const;
  // Everything of stats() but the measures: cheap, for the strand.
  SessionStats counters() const;

 private:
  struct Stroke {
    protocol::BrushTool tool;
    double radius, strength;
    Symmetry symmetry;
    bool accumulate = false;
    std::vector<StrokeDab> memory;  // empty when accumulating
    History::StepId step = 0;       // the history step its dabs last folded into
    StepAuthor by;
    std::optional<double> height;
    Volume start;  // the volume as the stroke began: rays pick on it, normals are read on it
    std::int64_t lastMessageMs = 0;  // the stroke clock at its begin or last stroke.dabs
    // At the last count (begin, or strokeHeldBytes through endStaleStrokes): the bricks of start
    // that the volume no longer held, and changedBricks_ then. Held bricks are at most heldBricks
    // plus the bricks changed since.
    std::size_t heldBricks = 0, changedAtCount = 0;
    std::optional<Plane> plane{};  // see beginStroke, "The stroke's plane"
    std::optional<WarpStroke> warp;  // a warp stroke: its state; start is its base
    std::uint64_t warpRevision = 0;  // the session's revision after its begin or last message
    std::optional<PaintSettings> paint{};  // a paint or mask stroke: its settings
  };

  ApplyResult warpDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool);
  ApplyResult paintDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool);
  // Remembers a brush's or paint stroke's applied images (unless it accumulates) and folds a
  // message that changed something into the stroke's step (strokeDabs).
  void foldMessage(StrokeId id, const Edit& message, const std::vector<StrokeDab>& images);
  // Folds a message that changed something into stroke s's step, or starts a new step when it
  // cannot grow (foldMessage, warpDabs).
  void foldIntoStep(Stroke& s, StrokeId id, const Edit& message);
  // The wire name of the stroke's tool, for its steps.
  static std::string_view toolName(const Stroke& s);

  ApplyResult finish(const Edit& edit);
  // finish(), its revision, change, ROI and bricks written into a stroke message's result.
  void finishInto(ApplyResult& result, const Edit& message);
  // Swaps the digest terms of bricks that went from `from` to what the volume now holds.
  void trackDigest(const std::vector<BrickChange>& changes, bool forward);
  // Forgets the cached terms (the volume was replaced without trackDigest).
  void resetDigest();
  void bump();
  // The result of an undo or redo that published `e` (null: there was nothing to move).
  HistoryResult historyMoved(const Edit* e);
  HistoryResult authorMoved(const History::AuthorMove& m, bool forward);
  // The record of a step made now, by `by` with `tool`, at the next revision.
  StepInfo stepInfo(const StepAuthor& by, std::string_view tool) const;
  // Throws LimitExceeded when kMaxOpenStrokes strokes are open: a new one must wait for an end.
  void checkStrokeRoom() const;
  const Stroke& openStroke(StrokeId id) const;
  // For History::push: whether `step` is the step of an open stroke other than `except`, which
  // its next dabs will fold into (it stays unpacked until the stroke ends).
  bool growingStep(History::StepId step, StrokeId except = 0) const;

  Volume volume_;
  History history_;
  std::uint64_t revision_;
  std::uint64_t digestTerms_;  // sum of brickDigestTerm over the live volume
  // The term of the buffer a brick got from its last change, with that buffer: a stroke
  // replaces the same bricks message after message, and the replaced brick's term is then
  // known instead of hashed again. Holding the buffer keeps its address from naming another
  // brick; it is the volume's own (resetDigest() drops them when it is replaced).
  // Direct-mapped: brick (x, y, z) has slot (x + nx (y + ny z)) mod the slot count, which is
  // the volume's brick count up to kMaxCachedTerms (about 0.75 MiB), made on the first change.
  // A slot names the brick it holds (key): a brick that shares it replaces it, and one not found
  // is hashed. A flat array, not a hash map: the lookups came after the engine's work had
  // evicted the map's nodes from the caches, and cost ~1% of the server's CPU
  // (docs/benchmark-log.md, capacity).
  struct CachedTerm {
    std::uint64_t key = kNoBrick;
    std::shared_ptr<const Brick> data;
    std::shared_ptr<const BrickPaint> paint;  // a paint stroke changes this and keeps data
    std::uint64_t term = 0;
  };
  static constexpr std::uint64_t kNoBrick = ~std::uint64_t(0);
  static constexpr std::size_t kMaxCachedTerms = std::size_t(1) << 14;
  std::vector<CachedTerm> cachedTerms_;
  std::map<StrokeId, Stroke> strokes_;
  StrokeId nextStroke_ = 1;
  // The stroke whose step is the newest change of the session (0: none); only its dabs may
  // fold into that step.
  StrokeId lastStroke_ = 0;
  std::function<std::int64_t()> clock_;
  std::size_t changedBricks_ = 0;  // brick changes published so far (trackDigest, load)
  std::function<std::int64_t()> strokeClock_;
};

}  // namespace marzipan::service
