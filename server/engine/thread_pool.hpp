// A fixed pool of worker threads that heavy kernels take explicitly.
// Kernels split work into items whose results do not depend on which thread runs them,
// so results are bit-identical for any thread count.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace marzipan {

// The cores this process may run on: its CPU affinity mask (taskset, a container's cpuset),
// which std::thread::hardware_concurrency ignores; at least 1. Every "one per core" default
// counts these, so a server pinned to one core does not start threads that take turns on it.
unsigned usableCores();

class ThreadPool {
 public:
  // threads <= 0 means one per usable core (usableCores). A pool of 1 runs everything on the caller.
  explicit ThreadPool(int threads = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return int(workers_.size()) + 1; }

  // Calls fn(i) for every i in [0, n), spread over the pool and the calling thread; returns
  // when all are done. The first exception thrown by fn is rethrown here. Callers do not wait
  // for each other: while one caller's items run on the pool, another's run on its own thread
  // (so fn may call parallelFor on the same pool; the inner call runs serially).
  void parallelFor(std::size_t n, const std::function<void(std::size_t)>& fn);

  // A single-threaded pool for callers that want no parallelism.
  static ThreadPool& serial();

  // How long a worker keeps looking for the next call before it sleeps, and the caller for
  // the workers' last items before it sleeps. A local tool calls parallelFor about ten times
  // with serial work of 0.05-0.3 ms between calls; a thread that sleeps in between must be
  // woken each time, and waking a sleeping core of a virtual machine took about as long as
  // the pieces themselves. While they look, the threads yield to any other runnable thread.
  static constexpr std::chrono::microseconds kSpin{300};

 private:
  void workerLoop();
  void runItems();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t jobSize_ = 0;
  std::size_t next_ = 0;
  std::size_t finished_ = 0;
  // Written under mutex_; read without it by the threads that look for work or for the end.
  std::atomic<std::size_t> generation_{0};
  std::atomic<bool> jobDone_{true};
  std::atomic<bool> stop_{false};
  int busy_ = 0;
  int sleepers_ = 0;  // workers waiting on wake_: only then is a call worth a notify
  std::exception_ptr error_;
  std::mutex callMutex_;
};

}  // namespace marzipan
