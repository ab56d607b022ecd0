// Progress and cooperative cancellation of long operations.
//
// A caller that may want to stop an operation, or to see how far it is, installs a Progress
// for its thread with Progress::Scope around the engine call. The chunked whole-volume passes
// (chunked_pass.hpp) pick it up when they start, check it before each chunk and count each
// chunk done. The local tools (level_set.hpp brushes and strokes, csg.hpp) pick it up too: they
// check it at least every few milliseconds of work (per slice of a dense loop, per bucket of
// the fast march) and count one unit per call, in fractions as their phases finish. Engine
// code never requires one: without a scope nothing is checked or counted.
//
// Conventions:
// - Work is counted in units the caller chooses (e.g. whole-volume passes); setTotal() says
//   how many the operation will take, advance() adds what is done, and the fraction reported
//   is done / total, clamped to [0, 1] and never decreasing. The first report comes one
//   interval after the Progress was made: an operation shorter than that reports nothing.
// - check() throws Cancelled once cancel() was called (from any thread). A cancelled engine
//   call may have published some of its passes; the caller restores the volume it copied
//   before the call (a Volume copy is cheap, see volume.hpp), so a cancelled operation
//   changes nothing. A cancelled local tool writes nothing back itself.
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
      : report_(std::move(report)), interval_(interval), lastReport_(std::chrono::steady_clock::now()) {}
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

// A share of an operation's Progress given to one phase of it (a local tool's gather, evolve
// or march): check() throws Cancelled when the operation was cancelled, advance(f) counts the
// fraction f of the share's units. Without a Progress (the default) neither does anything.
struct ProgressShare {
  Progress* progress = nullptr;
  double units = 0;

  bool cancelled() const { return progress && progress->cancelled(); }
  void check() const {
    if (progress) progress->check();
  }
  void advance(double fraction) const {
    if (progress) progress->advance(units * fraction);
  }
  ProgressShare part(double fraction) const { return {progress, units * fraction}; }
};

}  // namespace marzipan
