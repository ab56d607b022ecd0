// Undo/redo of whole steps for one session's volume.
//
// Conventions:
// - A step is the merged Edit (engine/edit.hpp) of one user action: one `tool.apply`, one
//   `volume.morph`, one global op, one `volume.load` of the same size, or one stroke of many
//   dabs (grown in place with amend()). Undo publishes the step's `before` bricks, redo its
//   `after` bricks, with the exact floats recorded, so the digest comes back bit for bit.
// - The caller passes the same volume the steps were recorded on, with no unrecorded change
//   in between (Session guarantees this). That is what lets a step keep only one side: while
//   it waits to be undone, the volume holds its `after` bricks, so only `before` is stored;
//   while it waits to be redone, the volume holds its `before`, so only `after` is stored. The
//   other side is read off the volume when the step moves.
// - Storage: the newest undo step stays as the Edit it was recorded as (shared brick buffers),
//   so that a stroke can amend() it, and so do the steps fold() grew under newer ones until
//   seal(); every other step is packed: its bricks' coordinates, a kind per brick (uniform
//   outside, uniform inside, data) and one zstd frame (level 1) of the
//   data bricks' voxels, each as its difference from the same voxel of the other side (the
//   volume's when the step moves; a prediction along x where that brick is uniform), split
//   into 4 byte planes (history.cpp); a brick's channels (BrickRef::paint, immutable and
//   shared like its voxels) are kept as they are, beside the frame. Packing is lossless: an unpacked brick holds the same
//   bits; about 4.5x smaller than the floats on the pig's strokes. A step is packed when a newer one is
//   pushed (an open stroke's step when its stroke ends: seal()), and repacked with its other
//   side when it moves between the lists.
// - Memory: bytes() is what the stored steps hold: for the unpacked step kBytesPerBrick per
//   brick buffer it references plus sizeof(BrickChange) per change (on the high side: its
//   `after` buffers are also the volume's), for packed steps their compressed frame plus the
//   coordinates and kinds (capacity, not size), and sizeof(BrickPaint) per channels buffer a step
//   references, packed or not (on the high side: the volume may share it). Uniform (null)
//   bricks cost no frame bytes.
//   Every step also counts what it holds whatever its bricks (kStepBytes: the step, its
//   StepInfo and its slot in the list) and the heap bytes of its strings (author id and name,
//   tool): a step of one uniform brick held ~13 counted bytes for ~400 real ones, so tiny
//   steps could hold many times the budget.
// - Earlier versions (volumeAt, rebuildAt): the later steps are gathered on the strand
//   (shared, not copied: a packed side is never changed, only replaced) and unpacked anywhere
//   (Rebuild::run). The last version built is kept (keep, keptAt) until a change of the
//   history could make it wrong (a step taken out of the middle, a fold under newer steps, a
//   clear): then it is dropped. It holds at most one volume's bricks more than the live one.
// - Budget: after push(), amend() and fold() the oldest steps are dropped until bytes() <= budget(),
//   even the newest one if it alone is larger; can_undo then says so. Undo and redo move a
//   step between the lists and repack it, which changes bytes() by the difference between
//   its two sides; they drop nothing. A new step clears the redo list.
// - Steps carry who made them (StepInfo): the caller's author, the tool, the wall-clock time
//   and the revision; History keeps them and moves them with the step, and reads only the
//   author's id (undoOf, redoOf).
// - Undo of one author's step (undoOf): the author's newest undo step is taken out of the
//   middle of the list when no later undo step (of anyone) touched any of its bricks; then
//   the volume there still holds its `after` bricks, and its `before` goes back bit for bit,
//   the later steps' bricks staying as they made them. That is the volume as if the step had
//   never been made whenever the steps commute (a later step did not read the step's bricks
//   either: a tool reads a margin around what it writes, a global op reads everything). Otherwise it
//   is refused, naming the first (oldest) later step that touched one of its bricks. The step
//   goes to the top of the redo list, so redo (session-wide) brings it back as the newest step.
//   redoOf(author) redoes the author's most recently undone step when no redo step above it
//   touched any of its bricks (those would be redone first), else refuses naming the nearest.
//   Invariant that makes both sound: every brick of the volume holds the `after` of the newest
//   undo step that touched it, and every redo step's references are what the volume will hold
//   once the redo steps above it are redone or taken out past it. A new step still clears the
//   redo list, an author's undone steps included.
// - Threading: not thread-safe; owned and called by one Session on its strand.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/edit.hpp"
#include "engine/volume.hpp"

namespace marzipan::service {

// One side (all `before` or all `after` bricks) of a step, losslessly compressed against the
// other side (its references), which the volume holds when the step is unpacked.
struct PackedBricks {
  std::vector<Int3> bricks;
  std::vector<std::uint8_t> kinds;     // per brick: kOutside, kInside or kData
  std::vector<unsigned char> frame;    // zstd frame of the kData bricks' records (history.cpp), in order,
                                       // then their low planes as they are (the zstd frame says where it ends)
  std::vector<std::shared_ptr<const BrickPaint>> paints;  // per brick its channels; empty: none has any
  std::uint64_t against = 0;           // fingerprint of the references
  static constexpr std::uint8_t kOutside = 0, kInside = 1, kData = 2;

  std::size_t bytes() const;
};

// Packs refs (one per brick, in order) against the same bricks' other side. Throws
// std::runtime_error only if zstd fails.
PackedBricks packBricks(const std::vector<Int3>& bricks, const std::vector<const BrickRef*>& refs,
                        const std::vector<const BrickRef*>& against);
// The refs packBricks() was given, as new buffers with the same bits (and the same channels
// buffers), given the same references;
// throws std::runtime_error for other references or a damaged frame.
std::vector<BrickRef> unpackBricks(const PackedBricks& p, const std::vector<const BrickRef*>& against);

// Who made a step. id is what undoOf() matches (a client id the caller chooses; empty: nobody
// can undo the step as theirs); name is for people (a display name).
struct StepAuthor {
  std::string id, name;
  friend bool operator==(const StepAuthor&, const StepAuthor&) = default;
};

// What a step is, for people and for the session's timeline.
struct StepInfo {
  // The session revision its last change produced: its name (history lists, conflicts, fork
  // points). A stroke folds several changes into one step: firstRevision is its first one's.
  std::uint64_t revision = 0, firstRevision = 0;
  StepAuthor author;
  std::string tool;       // the operation's wire name ("tool.apply" op name, a brush, "volume.load")
  std::int64_t timeMs = 0;  // wall clock of its first change, ms since the Unix epoch
  Box region;             // voxels it may have touched (clipped to the domain)
  Box bricks;             // bounding box of the bricks it changed, in brick coordinates (half-open)
  bool undone = false;    // set by list(): on the redo list
};

// The volume at an earlier revision (History::rebuildAt): gathered on the strand in
// O(later steps), built by run() on any thread, with no access to the History.
class Rebuild {
 public:
  std::uint64_t revision() const { return revision_; }
  // The voxels of the data bricks run() unpacks and publishes (its cost, for max_op_voxels).
  double voxels() const { return voxels_; }
  std::size_t steps() const { return later_.size(); }
  // The volume at revision(). Checks the thread's Progress (engine/progress.hpp) before each
  // step (Cancelled) and counts one unit per step. Throws std::runtime_error for a damaged step.
  Volume run() const;

 private:
  friend class History;
  explicit Rebuild(Volume base) : base_(std::move(base)) {}
  struct Later {
    std::optional<Edit> edit;
    std::shared_ptr<const PackedBricks> packed;
    Box region;
  };
  Volume base_;               // the live volume when gathered (bricks shared)
  std::vector<Later> later_;  // newest first
  std::uint64_t revision_ = 0, generation_ = 0;
  double voxels_ = 0;
};

class History {
 public:
  using StepId = std::uint64_t;  // 0 is never a step
  static constexpr std::size_t kDefaultBudgetBytes = std::size_t(256) << 20;
  static constexpr std::size_t kBytesPerBrick = sizeof(Brick) + 32;
  // What every step holds besides its bricks and strings (History::Step, its StepInfo, its
  // PackedBricks' shared block and a deque slot), rounded up; checked in test_history.cpp.
  static constexpr std::size_t kStepBytes = 512;

  explicit History(std::size_t budgetBytes = kDefaultBudgetBytes);

  // Records a step that has already been applied to the volume and clears the redo list.
  // An edit without changes records nothing and returns 0.
  // info.region and info.bricks are taken from the edit.
  // The step that was the newest is packed, unless `growing` says it is still growing (an open
  // stroke's step, which fold() will grow under the new one): it then stays unpacked, as a
  // folded step does, until seal() (packing it now would only have fold() unpack it again).
  StepId push(Edit step, StepInfo info = {}, const std::function<bool(StepId)>& growing = {});
  // Folds more changes (applied after the step) into step `id` if it is still the newest step,
  // unpacked (pushed or amended last) and nothing is undone; returns false (and records
  // nothing) otherwise, so the caller can push() a new step instead. The budget is enforced
  // afterwards.
  // revision (when not 0) becomes the step's revision.
  bool amend(StepId id, const Edit& more, std::uint64_t revision = 0);
  // Like amend(), but step `id` may be any undo step (an author's open stroke while others
  // sculpt elsewhere): folds `more` (applied to vol after the step) in when nothing is undone
  // and no later undo step touched any brick `more` changed, so that every brick still holds
  // the `after` of the newest step that touched it; false (nothing recorded) otherwise. A
  // packed step is unpacked against its own `after` bricks (vol's, with `more` and the later
  // steps taken back over them: the later steps are unpacked too, once) and stays unpacked,
  // so that the next fold costs what amend() does, until seal() or its move to the redo list
  // packs it.
  bool fold(StepId id, const Edit& more, const Volume& vol, std::uint64_t revision = 0);
  // Packs step `id` if fold() left it unpacked under newer steps (its stroke ended).
  void seal(StepId id);

  // Publishes the newest step's `before` bricks on vol and moves it to the redo list. Returns
  // the step with both sides (valid until the next call on this History), or null when there
  // is none.
  const Edit* undo(Volume& vol);
  // Publishes the most recently undone step's `after` bricks and moves it back.
  const Edit* redo(Volume& vol);
  // The step the last undo(), redo(), undoOf() or redoOf() moved (valid with its Edit).
  const StepInfo& moved() const { return movedInfo_; }

  // The outcome of undoOf()/redoOf(): Moved (edit and step as for undo()/redo()), Nothing (the
  // author has no step to move) or Conflict (nothing changed; conflict is the step in the way).
  struct AuthorMove {
    enum Outcome { Moved, Nothing, Conflict } outcome = Nothing;
    const Edit* edit = nullptr;
    StepInfo step;      // Moved: the step moved; Conflict: the author's step that was refused
    StepInfo conflict;  // Conflict: the first step that touched one of its bricks
  };
  // Undoes author's newest undo step (see the conventions). An empty author id has no steps.
  AuthorMove undoOf(Volume& vol, const std::string& author);
  // Redoes author's most recently undone step (see the conventions).
  AuthorMove redoOf(Volume& vol, const std::string& author);

  // The steps in history order: the undo list oldest first, then the redo list in the order
  // redo() would bring them back (undone set).
  std::vector<StepInfo> list() const;
  // At most `limit` steps of list() in reverse (the newest first: the redo list from the
  // furthest future, then the undo list newest first), starting after the step whose revision is
  // `before` (absent: at the first). found: `before` names a step (else nothing is listed);
  // more: steps remain after the last one listed. O(steps) to find `before`, then O(limit).
  struct Page {
    std::vector<StepInfo> steps;
    bool found = true, more = false;
  };
  Page page(std::optional<std::uint64_t> before, std::size_t limit) const;
  // The newest undo step (the one the last push or amend made, unless undone), or nullopt.
  std::optional<StepInfo> newest() const;
  // The undo step named by its revision, or nullopt.
  std::optional<StepInfo> find(std::uint64_t revision) const;
  // The volume right after the undo step `revision`, with the undo steps after it reverted: a
  // copy of live (which must be the volume the steps were recorded on, as for undo()) sharing
  // every other brick; live is not touched. Steps taken out by undoOf() are, in this view,
  // never made. nullopt when no undo step has that revision. Its revision() is `revision`.
  // Uses and fills the kept version (keep).
  std::optional<Volume> volumeAt(const Volume& live, std::uint64_t revision) const;
  // What volumeAt(live, revision) would build, to run off the strand; nullopt as volumeAt.
  std::optional<Rebuild> rebuildAt(const Volume& live, std::uint64_t revision) const;
  // The kept version of the undo step `revision`, if it is the one kept; nullopt otherwise.
  std::optional<Volume> keptAt(std::uint64_t revision) const;
  // Keeps what r.run() built (replacing the version kept before), unless the history changed
  // since r was gathered in a way that makes it wrong.
  void keep(const Rebuild& r, const Volume& built) const;

  void clear();

  bool canUndo() const { return !undo_.empty(); }
  bool canRedo() const { return !redo_.empty(); }
  std::size_t undoSteps() const { return undo_.size(); }
  std::size_t redoSteps() const { return redo_.size(); }
  std::size_t steps() const { return undo_.size() + redo_.size(); }
  // Undo steps held unpacked: the newest, and open strokes' steps (push's `growing`, fold()).
  std::size_t unpackedSteps() const;
  // Steps dropped so far because of the budget.
  std::size_t droppedSteps() const { return dropped_; }
  std::size_t bytes() const { return bytes_; }
  std::size_t budget() const { return budget_; }
  // A new budget applies from now on: steps are dropped at once if needed (oldest undo steps
  // first, then the redo steps furthest from the present).
  void setBudget(std::size_t budgetBytes);

 private:
  struct Step {
    StepId id;
    Box region;
    StepInfo info;
    std::optional<Edit> edit;  // the newest undo step before it is packed
    // undo list: `before` bricks; redo list: `after` bricks; null while edit is set. Shared
    // with Rebuilds in flight: replaced, never changed.
    std::shared_ptr<const PackedBricks> packed;

    std::size_t bytes() const;
  };

  void pack(Step& s);  // an unpacked undo step keeps its `before` side only
  void add(const Step& s) { bytes_ += s.bytes(); }
  void remove(const Step& s) { bytes_ -= s.bytes(); }
  void enforceBudget();
  // Moves undo_[i] to the top of the redo list / redo_[i] to the end of the undo list,
  // publishing its other side on vol.
  const Edit* moveToRedo(std::size_t i, Volume& vol);
  const Edit* moveToUndo(std::size_t i, Volume& vol);
  // The side of s that the volume does not hold, with the volume's side, as changes (before,
  // after); s on the undo list when undoSide. `at` gives the bricks the volume holds (vol's,
  // or a view of them with later steps taken back, as fold() needs).
  Edit sides(const Step& s, const std::function<BrickRef(const Int3&)>& at, bool undoSide) const;
  Edit sides(const Step& s, const Volume& vol, bool undoSide) const {
    return sides(s, [&](const Int3& b) { return vol.brick(b); }, undoSide);
  }
  // The index in undo_ of the step `revision`, or undo_.size().
  std::size_t undoIndex(std::uint64_t revision) const;
  // A change that alters the volume at some undo step's revision: the kept version goes.
  void rewritten();

  std::size_t budget_;
  std::deque<Step> undo_;  // oldest first; unpacked: the last, and folded ones until seal()
  std::deque<Step> redo_;  // most recently undone last; all packed
  std::size_t bytes_ = 0;
  std::size_t dropped_ = 0;
  StepId nextId_ = 1;
  Edit moved_;  // what undo()/redo() returned last
  StepInfo movedInfo_;
  std::uint64_t generation_ = 0;  // new at every rewritten()
  struct Kept {
    std::uint64_t revision = 0, generation = 0;
    Volume volume;
  };
  mutable std::optional<Kept> kept_;
};

}  // namespace marzipan::service
