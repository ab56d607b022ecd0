// An in-memory service::KeyValue with etcd's semantics (one global revision, createRevision kept
// until delete, leases deleting their keys), for the etcd store's unit tests. Leases expire only
// when a test says so (expire()); `down` makes every call throw KvUnavailable, and the next
// `loseAnswers` transactions are applied but throw as if their answer was lost on the way;
// `latency` delays every transaction (outside the lock) like a network round trip;
// the next `failRanges` reads (range()) throw KvUnavailable, after calling `onFailedRange` (if
// set) outside the lock, where a test may change the store as another server would meanwhile;
// `entriesRead` counts the entries range() returned;
// `stallKeepAlives` holds keep-alives up (as an etcd election does, no member answering for a
// while) until it is cleared, then they succeed: the lease itself does not expire.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "service/key_value.hpp"

namespace marzipan::test {

class MemoryKv : public service::KeyValue {
 public:
  using KvEntry = service::KvEntry;
  using KvCompare = service::KvCompare;
  using KvOp = service::KvOp;

  std::int64_t leaseGrant(std::int64_t ttl) override {
    const std::lock_guard lock(mutex_);
    check();
    leases_.insert(++lastLease_);
    (void)ttl;
    return lastLease_;
  }
  std::int64_t leaseKeepAlive(std::int64_t lease) override {
    while (stallKeepAlives) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    const std::lock_guard lock(mutex_);
    check();
    return leases_.count(lease) ? 5 : 0;
  }
  void leaseRevoke(std::int64_t lease) override {
    const std::lock_guard lock(mutex_);
    check();
    dropLease(lease);
  }
  // The lease runs out: its keys go, as etcd deletes them.
  void expire(std::int64_t lease) {
    const std::lock_guard lock(mutex_);
    dropLease(lease);
  }

  std::vector<KvEntry> range(const std::string& key, const std::string& end, std::int64_t limit) override {
    if (failRanges > 0 && failRanges-- > 0) {
      if (onFailedRange) onFailedRange();
      throw service::KvUnavailable("memory kv: the read failed");
    }
    const std::lock_guard lock(mutex_);
    check();
    auto out = rangeLocked(key, end, limit);
    entriesRead += out.size();
    return out;
  }

  service::KvTxnResult txn(const std::vector<KvCompare>& compares, const std::vector<KvOp>& success,
                           const std::vector<KvOp>& failure) override {
    std::this_thread::sleep_for(latency);
    const std::lock_guard lock(mutex_);
    check();
    ++txns;
    bool ok = true;
    for (const KvCompare& c : compares) {
      const auto it = data_.find(c.key);
      bool holds = false;
      if (c.target == KvCompare::Target::createRevision) {
        holds = (it == data_.end() ? 0 : it->second.createRevision) == c.revision;
      } else {
        holds = it != data_.end() && it->second.value == c.value;
      }
      if (c.result == KvCompare::Result::notEqual) holds = !holds;
      ok = ok && holds;
    }
    service::KvTxnResult r;
    r.succeeded = ok;
    bool wrote = false;
    for (const KvOp& op : ok ? success : failure) {
      if (op.kind == KvOp::Kind::range) {
        r.ranges.push_back(rangeLocked(op.key, op.rangeEnd, 0));
        continue;
      }
      if (!wrote) ++revision_;
      wrote = true;
      if (op.kind == KvOp::Kind::put) {
        KvEntry& e = data_[op.key];
        if (e.createRevision == 0) e.createRevision = revision_;
        e.key = op.key;
        e.value = op.value;
        e.modRevision = revision_;
        e.lease = op.lease;
      } else {
        for (const KvEntry& e : rangeLocked(op.key, op.rangeEnd, 0)) data_.erase(e.key);
      }
    }
    r.revision = revision_;
    if (loseAnswers > 0 && loseAnswers-- > 0) throw service::KvUnavailable("answer lost");
    return r;
  }

  std::atomic<bool> down{false};  // set by the test while the hub's threads call in
  std::atomic<bool> stallKeepAlives{false};  // cleared by the test before the owner stops
  std::chrono::milliseconds latency{0};  // of each transaction
  int loseAnswers = 0;
  int txns = 0;
  std::atomic<int> failRanges{0};
  std::function<void()> onFailedRange;
  std::atomic<std::size_t> entriesRead{0};

 private:
  void check() const {
    if (down) throw service::KvUnavailable("memory kv is down");
  }
  void dropLease(std::int64_t lease) {
    if (!leases_.erase(lease)) return;
    bool wrote = false;
    for (auto it = data_.begin(); it != data_.end();) {
      if (it->second.lease == lease) {
        it = data_.erase(it);
        wrote = true;
      } else {
        ++it;
      }
    }
    if (wrote) ++revision_;
  }
  std::vector<KvEntry> rangeLocked(const std::string& key, const std::string& end, std::int64_t limit) const {
    std::vector<KvEntry> out;
    if (end.empty()) {
      if (const auto it = data_.find(key); it != data_.end()) out.push_back(it->second);
      return out;
    }
    for (auto it = data_.lower_bound(key); it != data_.end() && (end == std::string(1, '\0') || it->first < end); ++it) {
      out.push_back(it->second);
      if (limit > 0 && static_cast<std::int64_t>(out.size()) == limit) break;
    }
    return out;
  }

  std::mutex mutex_;
  std::map<std::string, KvEntry> data_;
  std::set<std::int64_t> leases_;
  std::int64_t revision_ = 1, lastLease_ = 0;
};

}  // namespace marzipan::test
