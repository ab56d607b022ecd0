// The service's worker threads and the strands that serialize each session's work on them.
// Sessions post their work here; the network threads at most parse a message and post its work
// (they never run geometry).
//
// Conventions: tasks are std::function<void()> that must not throw (an exception escaping a
// task is caught, logged through the error hook and dropped). A Strand runs its tasks one at a
// time, in the order posted, on any worker; tasks of different strands run in parallel.
// Ownership: a Strand is held by shared_ptr; a posted task keeps its strand alive.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace marzipan::service {

class Workers {
 public:
  using Task = std::function<void()>;
  // threads == 0: one per usable core (usableCores, engine/thread_pool.hpp). onError gets what an escaping exception said.
  explicit Workers(unsigned threads, std::function<void(const std::string&)> onError = {});
  ~Workers();  // stop()
  Workers(const Workers&) = delete;
  Workers& operator=(const Workers&) = delete;

  unsigned threads() const { return count_; }
  void post(Task task);
  // Runs `task` once `delay` has passed (dropped if the workers stop first).
  void postAfter(std::chrono::milliseconds delay, Task task);
  // Runs the tasks already queued (not the delayed ones), then joins the threads. Idempotent.
  void stop();

  // Held by a task for the length of a long computation (a whole-volume operation): the
  // workers start one more thread meanwhile, which leaves again when the task ends, so long
  // tasks of some sessions never take every thread from the others' short ones (the kernel
  // then shares the cores among them).
  class LongTask {
   public:
    explicit LongTask(Workers& w);
    ~LongTask();
    LongTask(const LongTask&) = delete;
    LongTask& operator=(const LongTask&) = delete;

   private:
    Workers& workers_;
  };

 private:
  void loop();
  void reapRetired();

  std::function<void(const std::string&)> onError_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Task> ready_;
  std::multimap<std::chrono::steady_clock::time_point, Task> delayed_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
  unsigned count_ = 0;   // threads started by the constructor
  int retire_ = 0;       // extra threads that should leave when they find no task
  std::vector<std::thread::id> retired_;  // left the loop, not joined yet
};

class Strand : public std::enable_shared_from_this<Strand> {
 public:
  explicit Strand(Workers& workers) : workers_(workers) {}
  void post(Workers::Task task);
  // Tasks posted and not yet finished (for "finish running edits" at shutdown).
  std::size_t pending() const;

 private:
  void runOne();

  Workers& workers_;
  mutable std::mutex mutex_;
  std::deque<Workers::Task> tasks_;
  bool scheduled_ = false;  // a runOne is posted or running
};

}  // namespace marzipan::service
