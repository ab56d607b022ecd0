// etcd v3 reached through its JSON gateway (HTTP/1.1 POST /v3/..., keys and values base64,
// 64-bit numbers as JSON strings), as a service::KeyValue. No client library: etcd serves
// the gateway on its client port (3.4: /v3/kv/range, /v3/kv/txn, /v3/lease/grant, ...).
//
// Endpoints: "http://HOST:PORT" each (no TLS). A request goes to the endpoint that answered
// last; on a connection error, a timeout or an "unavailable" answer (a member without a
// leader) it goes to the next one, once round all of them, then throws KvUnavailable. Every
// request the store makes is safe to send again (see service/etcd_store.hpp), so a request
// whose answer was lost is retried like one never sent. etcd's own refusals (request too
// large, quota exceeded, too many operations in a transaction, a lease not found) throw
// KvRefused. Thread-safe: each request has its own connection.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "service/key_value.hpp"

namespace marzipan::net {

class EtcdClient : public service::KeyValue {
 public:
  // Throws std::invalid_argument for an empty list or an endpoint that is not http://HOST:PORT.
  explicit EtcdClient(std::vector<std::string> endpoints,
                      std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));
  // "http://a:2379,http://b:2379" as given to --etcd / MARZIPAN_ETCD.
  static std::vector<std::string> splitEndpoints(const std::string& list);

  std::int64_t leaseGrant(std::int64_t ttlSeconds) override;
  std::int64_t leaseKeepAlive(std::int64_t lease) override;
  void leaseRevoke(std::int64_t lease) override;
  std::vector<service::KvEntry> range(const std::string& key, const std::string& rangeEnd = {},
                                      std::int64_t limit = 0) override;
  service::KvTxnResult txn(const std::vector<service::KvCompare>& compares, const std::vector<service::KvOp>& success,
                           const std::vector<service::KvOp>& failure) override;

  // One member's view (POST /v3/maintenance/status to that endpoint only).
  struct MemberStatus {
    std::uint64_t memberId = 0, leader = 0;
  };
  MemberStatus status(const std::string& endpoint);
  const std::vector<std::string>& endpoints() const { return endpoints_; }

  // The POST itself: the answer's JSON, with failover as described above.
  nlohmann::json post(const std::string& path, const nlohmann::json& body);

 private:
  struct Endpoint {
    std::string host, port, text;
  };
  std::vector<std::string> endpoints_;
  std::vector<Endpoint> parsed_;
  std::chrono::milliseconds timeout_;
  std::atomic<std::size_t> preferred_{0};
};

std::string base64Encode(const std::string& bytes);
// Throws std::invalid_argument on a character outside the alphabet.
std::string base64Decode(const std::string& text);

}  // namespace marzipan::net
