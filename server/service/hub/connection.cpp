#include "service/hub/connection.hpp"

#include <algorithm>

namespace marzipan::service {

ConnectionQueue::Admission ConnectionQueue::push(Incoming& in, const HubLimits& limits, Clock::time_point now) {
  const std::size_t size = in.size();
  Admission a;
  const std::lock_guard lock(mutex_);
  if (closed_) return a;
  // Refill the request budget: a token bucket holding a burst of two seconds' worth.
  const double rate = double(limits.maxRequestsPerSecond);
  tokens_ = std::min(2 * rate, tokens_ + rate * std::chrono::duration<double>(now - refilled_).count());
  refilled_ = now;
  if (queue_.size() >= limits.maxPendingMessages)
    a.refusal = "too many requests in flight on this connection (" + std::to_string(limits.maxPendingMessages) +
                "); wait for answers before sending more";
  else if (tokens_ < 1)
    a.refusal = "more than " + std::to_string(limits.maxRequestsPerSecond) +
                " requests per second on this connection; slow down";
  else if (bytes_ + size > limits.maxBinaryBytes + limits.maxTextBytes)
    a.refusal = "too many bytes waiting on this connection; wait for answers before sending more";
  if (!a.refusal.empty()) return a;
  tokens_ -= 1;
  bytes_ += size;
  queue_.push_back(std::move(in));
  a.queued = true;
  if (!busy_) a.start = busy_ = true;
  return a;
}

ConnectionQueue::Next ConnectionQueue::take(Incoming& out) {
  const std::lock_guard lock(mutex_);
  if (closed_) return Next::Closed;
  if (queue_.empty()) {
    busy_ = false;
    return Next::Idle;
  }
  out = std::move(queue_.front());
  queue_.pop_front();
  bytes_ -= out.size();
  return Next::Message;
}

bool ConnectionQueue::takeText(Incoming& out) {
  const std::lock_guard lock(mutex_);
  if (closed_ || queue_.empty() || !std::holds_alternative<std::string>(queue_.front().message)) return false;
  out = std::move(queue_.front());
  queue_.pop_front();
  bytes_ -= out.size();
  return true;
}

void ConnectionQueue::putBack(Incoming in) {
  const std::lock_guard lock(mutex_);
  if (closed_) return;
  bytes_ += in.size();
  queue_.push_front(std::move(in));
}

ConnectionQueue::Next ConnectionQueue::finished() {
  const std::lock_guard lock(mutex_);
  if (closed_) return Next::Closed;
  if (queue_.empty()) {
    busy_ = false;
    return Next::Idle;
  }
  return Next::Message;
}

bool ConnectionQueue::close() {
  const std::lock_guard lock(mutex_);
  if (closed_) return false;
  closed_ = true;
  queue_.clear();
  bytes_ = 0;
  if (busy_) return false;  // the running owner cleans up when it finishes
  busy_ = true;             // busy stays set: nothing more runs
  return true;
}

bool ConnectionQueue::closed() const {
  const std::lock_guard lock(mutex_);
  return closed_;
}

}  // namespace marzipan::service
