// Prometheus text rendering of Metrics (see metrics.hpp for what each series means).
#include "net/metrics.hpp"

#include <sstream>

#include "service/etcd_store.hpp"
#include "service/hub.hpp"

namespace marzipan::net {

namespace {

void header(std::ostringstream& os, std::string_view name, std::string_view type, std::string_view help) {
  os << "# HELP " << name << ' ' << help << "\n# TYPE " << name << ' ' << type << '\n';
}

template <class Counts>
void histogram(std::ostringstream& os, std::string_view name, std::string_view help, const Counts& counts, double sum) {
  header(os, name, "histogram", help);
  std::uint64_t cumulative = 0;
  for (std::size_t i = 0; i < Metrics::kEditLatencyBuckets.size(); ++i) {
    cumulative += counts[i];
    os << name << "_bucket{le=\"" << Metrics::kEditLatencyBuckets[i] << "\"} " << cumulative << '\n';
  }
  cumulative += counts.back();
  os << name << "_bucket{le=\"+Inf\"} " << cumulative << '\n';
  os << name << "_sum " << sum << '\n';
  os << name << "_count " << cumulative << '\n';
}

}  // namespace

std::string_view pathClassName(PathClass c) {
  switch (c) {
    case PathClass::staticFile: return "static";
    case PathClass::healthz: return "healthz";
    case PathClass::metrics: return "metrics";
    case PathClass::websocket: return "ws";
  }
  return "static";
}

void Metrics::countRequest(PathClass c) { requests_[static_cast<std::size_t>(c)].fetch_add(1, std::memory_order_relaxed); }

void Metrics::countMethod(std::string_view method) {
  const std::lock_guard lock(mutex_);
  ++methods_[std::string(method)];
}

void Metrics::countError(int code) {
  const std::lock_guard lock(mutex_);
  ++errors_[code];
}

void Metrics::addBytesSent(std::uint64_t bytes) { bytesSent_.fetch_add(bytes, std::memory_order_relaxed); }
void Metrics::addSessions(std::int64_t delta) { sessions_.fetch_add(delta, std::memory_order_relaxed); }
void Metrics::addClients(std::int64_t delta) { clients_.fetch_add(delta, std::memory_order_relaxed); }

void Metrics::observe(LatencyCounts& counts, double& sum, double seconds) {
  std::size_t bucket = 0;
  while (bucket < kEditLatencyBuckets.size() && seconds > kEditLatencyBuckets[bucket]) ++bucket;
  ++counts[bucket];
  sum += seconds;
}

void Metrics::observeEditLatency(double seconds) {
  const std::lock_guard lock(mutex_);
  observe(latencyCounts_, latencySum_, seconds);
}

void Metrics::countOwnershipChange(bool gained) {
  (gained ? ownershipGained_ : ownershipLost_).fetch_add(1, std::memory_order_relaxed);
}
void Metrics::countFencedRejection() { fencedRejections_.fetch_add(1, std::memory_order_relaxed); }

void Metrics::observeEtcdAppend(double seconds) {
  const std::lock_guard lock(mutex_);
  observe(etcdAppendCounts_, etcdAppendSum_, seconds);
}

std::string Metrics::renderPrometheus() const {
  std::ostringstream os;
  os.precision(12);
  header(os, "marzipan_http_requests_total", "counter", "HTTP requests by path class.");
  for (std::size_t i = 0; i < kPathClassCount; ++i) {
    os << "marzipan_http_requests_total{path=\"" << pathClassName(static_cast<PathClass>(i)) << "\"} "
       << requests_[i].load(std::memory_order_relaxed) << '\n';
  }
  header(os, "marzipan_sessions", "gauge", "Sessions loaded.");
  os << "marzipan_sessions " << sessions_.load(std::memory_order_relaxed) << '\n';
  header(os, "marzipan_clients", "gauge", "WebSocket clients connected.");
  os << "marzipan_clients " << clients_.load(std::memory_order_relaxed) << '\n';
  header(os, "marzipan_bytes_sent_total", "counter", "Bytes written to clients.");
  os << "marzipan_bytes_sent_total " << bytesSent_.load(std::memory_order_relaxed) << '\n';

  const std::lock_guard lock(mutex_);
  header(os, "marzipan_rpc_requests_total", "counter", "JSON-RPC requests by method.");
  for (const auto& [method, count] : methods_) os << "marzipan_rpc_requests_total{method=\"" << method << "\"} " << count << '\n';
  header(os, "marzipan_errors_total", "counter", "Error responses by code (HTTP status or JSON-RPC code).");
  for (const auto& [code, count] : errors_) os << "marzipan_errors_total{code=\"" << code << "\"} " << count << '\n';
  histogram(os, "marzipan_edit_latency_seconds", "Time from an edit request to its reply.", latencyCounts_, latencySum_);
  header(os, "marzipan_etcd_ownership_changes_total", "counter", "Sessions this server took (gained) or let go (lost) in etcd.");
  os << "marzipan_etcd_ownership_changes_total{change=\"gained\"} " << ownershipGained_.load(std::memory_order_relaxed) << '\n';
  os << "marzipan_etcd_ownership_changes_total{change=\"lost\"} " << ownershipLost_.load(std::memory_order_relaxed) << '\n';
  header(os, "marzipan_etcd_fenced_rejections_total", "counter", "Writes etcd refused because another server owns the session now.");
  os << "marzipan_etcd_fenced_rejections_total " << fencedRejections_.load(std::memory_order_relaxed) << '\n';
  histogram(os, "marzipan_etcd_append_seconds", "Time of one journal transaction in etcd (a group of appends).",
            etcdAppendCounts_, etcdAppendSum_);
  return os.str();
}

service::HubEvents hubEventsFor(Metrics& metrics) {
  service::HubEvents e;
  e.sessions = [&metrics](std::int64_t d) { metrics.addSessions(d); };
  e.clients = [&metrics](std::int64_t d) { metrics.addClients(d); };
  e.request = [&metrics](std::string_view m) { metrics.countMethod(m); };
  e.error = [&metrics](int code) { metrics.countError(code); };
  e.editLatency = [&metrics](double s) { metrics.observeEditLatency(s); };
  return e;
}

service::EtcdEvents etcdEventsFor(Metrics& metrics) {
  service::EtcdEvents e;
  e.ownershipChanged = [&metrics](const std::string&, bool gained) { metrics.countOwnershipChange(gained); };
  e.fencedRejection = [&metrics](const std::string&) { metrics.countFencedRejection(); };
  e.appended = [&metrics](double s, std::size_t) { metrics.observeEtcdAppend(s); };
  return e;
}

}  // namespace marzipan::net
