// Progress and cooperative cancellation of long whole-volume operations.
//
// A caller that may want to stop an operation, or to see how far it is, installs a Progress
// for its thread with Progress::Scope around the engine call. The chunked whole-volume passes
// (chunked_pass.hpp) pick it up when they start, check it before each chunk and count each
// chunk done. Engine code never requires one: without a scope nothing is checked or counted.
//
// Conventions:
// - Work is counted in units the caller chooses (e.g. whole-volume passes); setTotal() says
//   how many the operation will take, advance() adds what is done, and the fraction reported
//   is done / total, clamped to [0, 1] and never decreasing.
// - check() throws Cancelled once cancel() was called (from any thread). A cancelled engine
//   call may have published some of its passes; the caller restores the volume it copied
//   before the call (a Volume copy is cheap, see volume.hpp), so a cancelled operation
//   changes nothing.
// - Thread safety: cancel(), cancelled(), check() and advance() may be called from any thread;
//   the report callback runs on the thread that crossed the reporting interval, at most once
//   per interval, never concurrently with itself. An exception it throws propagates out of
//   advance() (and so out of the engine call, like any failure of the operation).
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <stdexcept>

namespace marzipan {

class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("the operation was cancelled") {}
};

class Progress {
 public:
  using Report = std::function<void(double fraction)>;

  Progress() = default;
  explicit Progress(Report report, std::chrono::milliseconds interval = std::chrono::milliseconds(250))
      : report_(std::move(report)), interval_(interval) {}
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void cancel() { cancelled_.store(true, std::memory_order_relaxed); }
  bool cancelled() const { return cancelled_.load(std::memory_order_relaxed); }
  void check() const {
    if (cancelled()) throw Cancelled();
  }

  void setTotal(double units) { total_.store(units, std::memory_order_relaxed); }
  // Adds finished work and reports the fraction when the interval has passed since the last
  // report.
  void advance(double units);
  double fraction() const;

  // The Progress of the calling thread's current operation, or null.
  static Progress* current();

  // Installs p as the calling thread's current Progress for the scope's lifetime.
  class Scope {
   public:
    explicit Scope(Progress& p);
    ~Scope();
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    Progress* previous_;
  };

 private:
  Report report_;
  std::chrono::milliseconds interval_{250};
  std::atomic<bool> cancelled_{false};
  std::atomic<double> total_{1}, done_{0};
  std::mutex reportMutex_;
  std::chrono::steady_clock::time_point lastReport_{};
  double reported_ = 0;
};

}  // namespace marzipan
