#include "thread_pool.hpp"

#include <utility>

namespace marzipan {

ThreadPool::ThreadPool(int threads) {
  if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
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
  std::size_t seen = generation_;
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    ++busy_;
    runItems();
    --busy_;
    if (finished_ == jobSize_ && busy_ == 0) done_.notify_all();
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
  ++generation_;
  wake_.notify_all();
  runItems();
  // Workers that woke late may still be between claiming and finishing; wait for all of them
  // so that fn is not referenced after we return.
  done_.wait(lock, [&] { return finished_ == jobSize_ && busy_ == 0; });
  job_ = nullptr;
  jobSize_ = 0;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

}  // namespace marzipan
