// Workers and Strand (see workers.hpp). A strand keeps one runOne in the workers' queue at a
// time; runOne runs a single task and re-posts itself, so a busy strand shares the workers
// fairly with others instead of holding a thread until its queue is empty.
#include "service/workers.hpp"

#include "engine/thread_pool.hpp"

#include <algorithm>
#include <exception>

namespace marzipan::service {

Workers::Workers(unsigned threads, std::function<void(const std::string&)> onError) : onError_(std::move(onError)) {
  if (threads == 0) threads = usableCores();
  count_ = threads;
  for (unsigned i = 0; i < threads; ++i) threads_.emplace_back([this] { loop(); });
}

Workers::LongTask::LongTask(Workers& w) : workers_(w) {
  w.reapRetired();
  const std::lock_guard lock(w.mutex_);
  if (w.stopping_) return;
  w.threads_.emplace_back([&w] { w.loop(); });
}

Workers::LongTask::~LongTask() {
  {
    const std::lock_guard lock(workers_.mutex_);
    if (workers_.stopping_) return;
    ++workers_.retire_;
  }
  workers_.wake_.notify_one();
}

// Joins the extra threads that have left (outside the lock: they take it on their way out).
void Workers::reapRetired() {
  std::vector<std::thread> done;
  {
    const std::lock_guard lock(mutex_);
    if (stopping_) return;
    for (const std::thread::id id : retired_) {
      const auto it = std::find_if(threads_.begin(), threads_.end(), [&](const std::thread& t) { return t.get_id() == id; });
      if (it == threads_.end()) continue;
      done.push_back(std::move(*it));
      threads_.erase(it);
    }
    retired_.clear();
  }
  for (std::thread& t : done) t.join();
}

Workers::~Workers() { stop(); }

void Workers::post(Task task) {
  {
    const std::lock_guard lock(mutex_);
    if (stopping_ && threads_.empty()) return;
    ready_.push_back(std::move(task));
  }
  wake_.notify_one();
}

void Workers::postAfter(std::chrono::milliseconds delay, Task task) {
  {
    const std::lock_guard lock(mutex_);
    if (stopping_) return;
    delayed_.emplace(std::chrono::steady_clock::now() + delay, std::move(task));
  }
  wake_.notify_one();
}

void Workers::stop() {
  {
    const std::lock_guard lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
    delayed_.clear();
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
  const std::lock_guard lock(mutex_);
  threads_.clear();
  ready_.clear();
}

void Workers::loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    while (!delayed_.empty() && delayed_.begin()->first <= now) {
      ready_.push_back(std::move(delayed_.begin()->second));
      delayed_.erase(delayed_.begin());
    }
    if (!ready_.empty()) {
      Task task = std::move(ready_.front());
      ready_.pop_front();
      lock.unlock();
      try {
        task();
      } catch (const std::exception& e) {
        if (onError_) onError_(std::string("worker task failed: ") + e.what());
      } catch (...) {
        if (onError_) onError_("worker task failed");
      }
      task = nullptr;  // its captures die outside the lock too
      lock.lock();
      continue;
    }
    if (stopping_) return;
    if (retire_ > 0) {
      // Any idle thread may leave in place of the long task's: they are all alike.
      --retire_;
      retired_.push_back(std::this_thread::get_id());
      return;
    }
    if (delayed_.empty()) {
      wake_.wait(lock);
    } else {
      // A copy: stop() or another worker may erase that entry while this one waits.
      const auto due = delayed_.begin()->first;
      wake_.wait_until(lock, due);
    }
  }
}

void Strand::post(Workers::Task task) {
  {
    const std::lock_guard lock(mutex_);
    tasks_.push_back(std::move(task));
    if (scheduled_) return;
    scheduled_ = true;
  }
  workers_.post([self = shared_from_this()] { self->runOne(); });
}

std::size_t Strand::pending() const {
  const std::lock_guard lock(mutex_);
  return tasks_.size() + (scheduled_ ? 1 : 0);
}

void Strand::runOne() {
  Workers::Task task;
  {
    const std::lock_guard lock(mutex_);
    task = std::move(tasks_.front());
    tasks_.pop_front();
  }
  struct Next {
    Strand& s;
    ~Next() {
      bool again;
      {
        const std::lock_guard lock(s.mutex_);
        again = !s.tasks_.empty();
        s.scheduled_ = again;
      }
      if (again) s.workers_.post([self = s.shared_from_this()] { self->runOne(); });
    }
  } next{*this};
  task();
}

}  // namespace marzipan::service
