// A transactional key-value store with leases, shaped after etcd's v3 API: what the etcd-owned
// sessions (service/etcd_store.hpp) need from it, and nothing of how it is reached. The server
// implements it over etcd's JSON gateway (net/etcd_client.hpp); tests use an in-memory one.
//
// Conventions: keys and values are byte strings; a range is [key, rangeEnd) in byte order (an
// empty rangeEnd: the one key). Revisions are the store's global, strictly increasing counter:
// a key's createRevision is the revision of the write that created it (0 in a compare: absent)
// and stays until the key is deleted. Lease ids are > 0; 0 means no lease. TTLs in seconds.
// Errors: KvUnavailable when no member answered in time (the outcome of a write is then
// unknown); KvRefused when the store refused the request itself (too large, quota exceeded,
// too many operations): the write did not happen, and retrying it will not help.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace marzipan::service {

struct KvUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct KvRefused : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct KvEntry {
  std::string key, value;
  std::int64_t createRevision = 0, modRevision = 0, lease = 0;
};

struct KvCompare {
  enum class Target { createRevision, value };
  enum class Result { equal, notEqual };
  std::string key;
  Target target = Target::createRevision;
  Result result = Result::equal;
  std::int64_t revision = 0;  // for createRevision
  std::string value;          // for value
};

struct KvOp {
  enum class Kind { put, deleteRange, range };
  Kind kind = Kind::put;
  std::string key, rangeEnd, value;  // value for put; rangeEnd for deleteRange and range
  std::int64_t lease = 0;            // for put
};

struct KvTxnResult {
  bool succeeded = false;
  std::int64_t revision = 0;                // the store's revision after the transaction
  std::vector<std::vector<KvEntry>> ranges;  // per range op of the branch that ran, in order
};

class KeyValue {
 public:
  virtual ~KeyValue() = default;

  virtual std::int64_t leaseGrant(std::int64_t ttlSeconds) = 0;
  // Renews the lease; returns its TTL, <= 0 when it has expired or was revoked.
  virtual std::int64_t leaseKeepAlive(std::int64_t lease) = 0;
  // Deletes the lease and every key attached to it.
  virtual void leaseRevoke(std::int64_t lease) = 0;

  // The entries of [key, rangeEnd), in key order, at most `limit` (0: all).
  virtual std::vector<KvEntry> range(const std::string& key, const std::string& rangeEnd = {}, std::int64_t limit = 0) = 0;
  // If every compare holds, runs `success`, else `failure`; atomically.
  virtual KvTxnResult txn(const std::vector<KvCompare>& compares, const std::vector<KvOp>& success,
                          const std::vector<KvOp>& failure) = 0;
};

// The rangeEnd that covers every key starting with `prefix` (etcd's "prefix end").
std::string prefixEnd(std::string prefix);

}  // namespace marzipan::service
