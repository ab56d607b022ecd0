// The server's counters, rendered for GET /metrics in the Prometheus text exposition format
// (version 0.0.4). Beast-free and thread-safe: any I/O or worker thread may update them.
//
// Conventions: durations in seconds, sizes in bytes; counters only grow, gauges (sessions,
// clients) move by deltas. The HTTP layer feeds requests, errors (HTTP status >= 400) and
// bytes sent; the WebSocket layer feeds sessions, clients (in sessions), requests by method and
// the edit latency histogram; the etcd store (--etcd) feeds ownership changes, fenced rejections
// and the latency of its journal transactions. Errors are labelled by code: HTTP statuses now, JSON-RPC
// codes (negative) once the WebSocket layer reports them.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

namespace marzipan::service {
struct HubEvents;
struct EtcdEvents;
}

namespace marzipan::net {

// What a request asked for, as a bounded label (never the raw path).
enum class PathClass { staticFile, healthz, metrics, websocket };
inline constexpr std::size_t kPathClassCount = 4;
std::string_view pathClassName(PathClass c);  // "static", "healthz", "metrics", "ws"

class Metrics {
 public:
  // Upper bounds of the edit latency histogram's buckets, seconds (+Inf is implied).
  static constexpr std::array<double, 11> kEditLatencyBuckets{0.001, 0.002, 0.005, 0.008, 0.016, 0.032,
                                                              0.064, 0.128, 0.256, 0.512, 1.024};

  void countRequest(PathClass c);
  // A JSON-RPC request by its method name (one of PROTOCOL.md's: the label set stays bounded).
  void countMethod(std::string_view method);
  void countError(int code);
  void addBytesSent(std::uint64_t bytes);
  void addSessions(std::int64_t delta);
  void addClients(std::int64_t delta);
  void observeEditLatency(double seconds);
  // etcd-owned sessions (service/etcd_store.hpp).
  void countOwnershipChange(bool gained);
  void countFencedRejection();
  void observeEtcdAppend(double seconds);

  std::string renderPrometheus() const;

 private:
  std::array<std::atomic<std::uint64_t>, kPathClassCount> requests_{};
  std::atomic<std::uint64_t> bytesSent_{0};
  std::atomic<std::int64_t> sessions_{0}, clients_{0};
  mutable std::mutex mutex_;  // guards the two below
  std::map<int, std::uint64_t> errors_;
  std::map<std::string, std::uint64_t, std::less<>> methods_;
  using LatencyCounts = std::array<std::uint64_t, kEditLatencyBuckets.size() + 1>;  // per bucket, last = +Inf
  static void observe(LatencyCounts& counts, double& sum, double seconds);
  LatencyCounts latencyCounts_{}, etcdAppendCounts_{};
  double latencySum_ = 0, etcdAppendSum_ = 0;
  std::atomic<std::uint64_t> ownershipGained_{0}, ownershipLost_{0}, fencedRejections_{0};
};

// The hub's events wired to these counters (sessions, clients, requests by method, errors,
// edit latency); `log` is left to the caller. The metrics must outlive the hub.
service::HubEvents hubEventsFor(Metrics& metrics);
// The etcd store's events wired to these counters (`log` is left to the caller).
service::EtcdEvents etcdEventsFor(Metrics& metrics);

}  // namespace marzipan::net
