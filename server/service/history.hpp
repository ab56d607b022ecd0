// Undo/redo of whole steps for one session's volume.
//
// Conventions:
// - A step is the merged Edit (engine/edit.hpp) of one user action: one `tool.apply`, one
//   `volume.morph`, one global op, one `volume.load` of the same size, or one stroke of many
//   dabs (grown in place with amend()). Undo publishes the step's `before` bricks, redo its
//   `after` bricks; since bricks are immutable and shared, this restores the exact field, so
//   the digest comes back bit for bit.
// - The caller passes the same volume the steps were recorded on, with no unrecorded change
//   in between (Session guarantees this); History never looks at the volume otherwise.
// - Memory: bytes() counts every distinct brick buffer referenced by a stored step once
//   (kBytesPerBrick each: the 2 KB of floats plus the shared_ptr control block) plus
//   sizeof(BrickChange) per recorded change. It is approximate on the high side: a buffer that
//   is also the live version of its brick is counted although undo keeps it alive only
//   together with the volume. Uniform (null) bricks cost nothing.
// - Budget: after push() and amend() the oldest steps are dropped until bytes() <= budget(),
//   even the newest one if it alone is larger; can_undo then says so. Undo and redo only move
//   steps between the two lists and never change bytes(). A new step clears the redo list.
// - Threading: not thread-safe; owned and called by one Session on its strand.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <unordered_map>

#include "engine/edit.hpp"
#include "engine/volume.hpp"

namespace marzipan::service {

class History {
 public:
  using StepId = std::uint64_t;  // 0 is never a step
  static constexpr std::size_t kDefaultBudgetBytes = std::size_t(256) << 20;
  static constexpr std::size_t kBytesPerBrick = sizeof(Brick) + 32;

  explicit History(std::size_t budgetBytes = kDefaultBudgetBytes);

  // Records a step that has already been applied to the volume and clears the redo list.
  // An edit without changes records nothing and returns 0.
  StepId push(Edit step);
  // Folds more changes (applied after the step) into step `id` if it is still the newest step
  // and nothing is undone; returns false (and records nothing) otherwise, so the caller can
  // push() a new step instead. The budget is enforced afterwards.
  bool amend(StepId id, const Edit& more);

  // Publishes the newest step's `before` bricks on vol and moves it to the redo list. Returns
  // the step (valid until the next call that changes the history), or null when there is none.
  const Edit* undo(Volume& vol);
  // Publishes the most recently undone step's `after` bricks and moves it back.
  const Edit* redo(Volume& vol);

  void clear();

  bool canUndo() const { return !undo_.empty(); }
  bool canRedo() const { return !redo_.empty(); }
  std::size_t undoSteps() const { return undo_.size(); }
  std::size_t redoSteps() const { return redo_.size(); }
  std::size_t steps() const { return undo_.size() + redo_.size(); }
  // Steps dropped so far because of the budget.
  std::size_t droppedSteps() const { return dropped_; }
  std::size_t bytes() const;
  std::size_t budget() const { return budget_; }
  // A new budget applies from now on: steps are dropped at once if needed (oldest undo steps
  // first, then the redo steps furthest from the present).
  void setBudget(std::size_t budgetBytes);

 private:
  struct Step {
    StepId id;
    Edit edit;
  };

  void retain(const Edit& e);
  void release(const Edit& e);
  void enforceBudget();

  std::size_t budget_;
  std::deque<Step> undo_;  // oldest first
  std::deque<Step> redo_;  // most recently undone last
  // How many stored changes reference each brick buffer. The steps own the buffers, so a
  // pointer with a positive count cannot be reused by another allocation.
  std::unordered_map<const Brick*, std::size_t> refs_;
  std::size_t changeCount_ = 0;
  std::size_t dropped_ = 0;
  StepId nextId_ = 1;
};

}  // namespace marzipan::service
