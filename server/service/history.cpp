// Undo/redo of whole steps (see history.hpp).
#include "service/history.hpp"

#include <utility>

namespace marzipan::service {

History::History(std::size_t budgetBytes) : budget_(budgetBytes) {}

void History::retain(const Edit& e) {
  changeCount_ += e.changes.size();
  for (const auto& c : e.changes) {
    if (c.before.data) ++refs_[c.before.data.get()];
    if (c.after.data) ++refs_[c.after.data.get()];
  }
}

void History::release(const Edit& e) {
  changeCount_ -= e.changes.size();
  const auto drop = [&](const BrickRef& r) {
    if (!r.data) return;
    const auto it = refs_.find(r.data.get());
    if (--it->second == 0) refs_.erase(it);
  };
  for (const auto& c : e.changes) {
    drop(c.before);
    drop(c.after);
  }
}

std::size_t History::bytes() const {
  return refs_.size() * kBytesPerBrick + changeCount_ * sizeof(BrickChange);
}

void History::enforceBudget() {
  while (!undo_.empty() && bytes() > budget_) {
    release(undo_.front().edit);
    undo_.pop_front();
    ++dropped_;
  }
  // Only a smaller budget can leave redo steps over it: the furthest future goes first.
  while (!redo_.empty() && bytes() > budget_) {
    release(redo_.front().edit);
    redo_.pop_front();
    ++dropped_;
  }
}

History::StepId History::push(Edit step) {
  if (step.empty()) return 0;
  for (const auto& s : redo_) release(s.edit);
  redo_.clear();
  const StepId id = nextId_++;
  retain(step);
  undo_.push_back({id, std::move(step)});
  enforceBudget();
  return id;
}

bool History::amend(StepId id, const Edit& more) {
  if (id == 0 || undo_.empty() || !redo_.empty() || undo_.back().id != id) return false;
  Edit& e = undo_.back().edit;
  release(e);
  e.append(more.changes, more.region);
  if (e.empty()) {
    // The step now ends where it started: nothing is left to undo.
    undo_.pop_back();
    return true;
  }
  retain(e);
  enforceBudget();
  return true;
}

const Edit* History::undo(Volume& vol) {
  if (undo_.empty()) return nullptr;
  redo_.push_back(std::move(undo_.back()));
  undo_.pop_back();
  vol.publish(redo_.back().edit.changes, false);
  return &redo_.back().edit;
}

const Edit* History::redo(Volume& vol) {
  if (redo_.empty()) return nullptr;
  undo_.push_back(std::move(redo_.back()));
  redo_.pop_back();
  vol.publish(undo_.back().edit.changes, true);
  return &undo_.back().edit;
}

void History::clear() {
  undo_.clear();
  redo_.clear();
  refs_.clear();
  changeCount_ = 0;
}

void History::setBudget(std::size_t budgetBytes) {
  budget_ = budgetBytes;
  enforceBudget();
}

}  // namespace marzipan::service
