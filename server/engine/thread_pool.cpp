#include "thread_pool.hpp"

#include <algorithm>
#include <utility>
#if defined(__linux__)
#include <sched.h>
#endif
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace marzipan {

namespace {

// Waits while waiting() holds, for at most ThreadPool::kSpin, yielding the core to any other
// runnable thread now and then. True when waiting() stopped holding.
template <class Waiting>
bool spinWhile(Waiting waiting) {
  const auto until = std::chrono::steady_clock::now() + ThreadPool::kSpin;
  for (unsigned i = 1; waiting(); ++i) {
#if defined(__SSE2__)
    _mm_pause();
#endif
    if (i % 64 == 0) {
      if (std::chrono::steady_clock::now() >= until) return false;
      std::this_thread::yield();
    }
  }
  return true;
}

}  // namespace

unsigned usableCores() {
#if defined(__linux__)
  cpu_set_t set;
  CPU_ZERO(&set);
  // The calling thread's mask: a process started under taskset gives it to every thread.
  if (sched_getaffinity(0, sizeof set, &set) == 0) return unsigned(std::max(1, CPU_COUNT(&set)));
#endif
  return std::max(1u, std::thread::hardware_concurrency());
}

ThreadPool::ThreadPool(int threads) {
  if (threads <= 0) threads = int(usableCores());
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this] { workerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& w : workers_) w.join();
}

ThreadPool& ThreadPool::serial() {
  static ThreadPool pool(1);
  return pool;
}

// Claims items one at a time until none are left; called with mutex_ held, returns with it held.
void ThreadPool::runItems() {
  while (next_ < jobSize_) {
    const std::size_t i = next_++;
    const auto* job = job_;
    mutex_.unlock();
    std::exception_ptr err;
    try {
      (*job)(i);
    } catch (...) {
      err = std::current_exception();
    }
    mutex_.lock();
    if (err && !error_) error_ = err;
    ++finished_;
  }
}

void ThreadPool::workerLoop() {
  std::unique_lock lock(mutex_);
  // The generation the pool was made with: a call made before this thread first got here is
  // still new to it (reading generation_ here missed it, and the caller did all its items).
  std::size_t seen = 0;
  for (;;) {
    if (!stop_ && generation_ == seen) {
      lock.unlock();
      spinWhile([&] { return generation_.load(std::memory_order_acquire) == seen && !stop_.load(std::memory_order_relaxed); });
      lock.lock();
      // A call that came after the look is seen here, under the lock it was made under.
      ++sleepers_;
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      --sleepers_;
    }
    if (stop_) return;
    seen = generation_;
    ++busy_;
    runItems();
    --busy_;
    if (finished_ == jobSize_ && busy_ == 0) {
      jobDone_ = true;
      done_.notify_all();
    }
  }
}

void ThreadPool::parallelFor(std::size_t n, const std::function<void(std::size_t)>& fn) {
  if (n == 0) return;
  // A caller that finds the pool busy with another caller's items runs its own on its thread
  // instead of queueing behind them: a long whole-volume operation of one session must not
  // hold up a render of another (items are independent, so the result is the same).
  std::unique_lock call(callMutex_, std::defer_lock);
  if (workers_.empty() || n == 1 || !call.try_lock()) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::unique_lock lock(mutex_);
  job_ = &fn;
  jobSize_ = n;
  next_ = 0;
  finished_ = 0;
  error_ = nullptr;
  jobDone_ = false;
  ++generation_;
  if (sleepers_ > 0) wake_.notify_all();
  runItems();
  // Workers that woke late may still be between claiming and finishing; wait for all of them
  // so that fn is not referenced after we return.
  if (!(finished_ == jobSize_ && busy_ == 0)) {
    lock.unlock();
    spinWhile([&] { return !jobDone_.load(std::memory_order_acquire); });
    lock.lock();
  }
  done_.wait(lock, [&] { return finished_ == jobSize_ && busy_ == 0; });
  job_ = nullptr;
  jobSize_ = 0;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

}  // namespace marzipan
