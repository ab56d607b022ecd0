#include "progress.hpp"

#include <algorithm>

namespace marzipan {

namespace {
thread_local Progress* tCurrent = nullptr;
}

Progress* Progress::current() { return tCurrent; }

Progress::Scope::Scope(Progress& p) : previous_(tCurrent) { tCurrent = &p; }
Progress::Scope::~Scope() { tCurrent = previous_; }

double Progress::fraction() const {
  const double total = total_.load(std::memory_order_relaxed);
  if (!(total > 0)) return 0;
  return std::clamp(done_.load(std::memory_order_relaxed) / total, 0.0, 1.0);
}

void Progress::advance(double units) {
  double done = done_.load(std::memory_order_relaxed);
  while (!done_.compare_exchange_weak(done, done + units, std::memory_order_relaxed)) {
  }
  if (!report_) return;
  // A thread that finds another reporting skips: the next advance reports the newer fraction.
  std::unique_lock lock(reportMutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - lastReport_ < interval_) return;
  const double f = std::max(reported_, fraction());
  lastReport_ = now;
  reported_ = f;
  report_(f);
}

}  // namespace marzipan
