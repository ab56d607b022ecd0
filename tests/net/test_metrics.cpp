// metrics: the Prometheus text format (0.0.4) and the counters behind it.
#include <catch2/catch.hpp>

#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "net/metrics.hpp"
#include "service/etcd_store.hpp"

using marzipan::net::Metrics;
using marzipan::net::PathClass;

namespace {

bool hasLine(const std::string& text, const std::string& line) {
  std::istringstream s(text);
  for (std::string l; std::getline(s, l);) {
    if (l == line) return true;
  }
  return false;
}

}  // namespace

TEST_CASE("metrics: a fresh registry renders every series at zero", "[net][metrics]") {
  const std::string text = Metrics().renderPrometheus();
  for (const char* line : {"marzipan_http_requests_total{path=\"static\"} 0", "marzipan_http_requests_total{path=\"healthz\"} 0",
                           "marzipan_http_requests_total{path=\"metrics\"} 0", "marzipan_http_requests_total{path=\"ws\"} 0",
                           "marzipan_sessions 0", "marzipan_clients 0", "marzipan_bytes_sent_total 0",
                           "marzipan_edit_latency_seconds_bucket{le=\"+Inf\"} 0", "marzipan_edit_latency_seconds_sum 0",
                           "marzipan_edit_latency_seconds_count 0", "# TYPE marzipan_errors_total counter",
                           "# TYPE marzipan_edit_latency_seconds histogram", "# TYPE marzipan_sessions gauge"}) {
    INFO(line);
    CHECK(hasLine(text, line));
  }
}

TEST_CASE("metrics: every line is a comment or `name{labels} value`", "[net][metrics]") {
  Metrics m;
  m.countRequest(PathClass::healthz);
  m.countError(404);
  m.countError(-32602);
  m.observeEditLatency(0.003);
  const std::regex sample(R"(marzipan_[a-z_]+(\{[a-z]+="[^"]*"\})? -?[0-9.e+-]+)");
  const std::regex comment(R"(# (HELP|TYPE) marzipan_[a-z_]+ .+)");
  std::istringstream s(m.renderPrometheus());
  int samples = 0;
  for (std::string line; std::getline(s, line);) {
    INFO(line);
    const bool isSample = std::regex_match(line, sample);
    CHECK((isSample || std::regex_match(line, comment)));
    samples += isSample;
  }
  CHECK(samples == 4 + 3 + 2 + int(Metrics::kEditLatencyBuckets.size()) + 3 + 2 + 1 +
                       int(Metrics::kEditLatencyBuckets.size()) + 3);
}

TEST_CASE("metrics: counters, gauges and errors by code", "[net][metrics]") {
  Metrics m;
  m.countRequest(PathClass::staticFile);
  m.countRequest(PathClass::staticFile);
  m.countRequest(PathClass::metrics);
  m.countError(404);
  m.countError(404);
  m.countError(-32602);
  m.addBytesSent(100);
  m.addBytesSent(23);
  m.addSessions(2);
  m.addClients(3);
  m.addClients(-1);
  const std::string text = m.renderPrometheus();
  CHECK(hasLine(text, "marzipan_http_requests_total{path=\"static\"} 2"));
  CHECK(hasLine(text, "marzipan_http_requests_total{path=\"metrics\"} 1"));
  CHECK(hasLine(text, "marzipan_errors_total{code=\"404\"} 2"));
  CHECK(hasLine(text, "marzipan_errors_total{code=\"-32602\"} 1"));
  CHECK(hasLine(text, "marzipan_bytes_sent_total 123"));
  CHECK(hasLine(text, "marzipan_sessions 2"));
  CHECK(hasLine(text, "marzipan_clients 2"));
}

TEST_CASE("metrics: the edit latency histogram is cumulative, bounds inclusive", "[net][metrics]") {
  Metrics m;
  m.observeEditLatency(0.001);  // exactly on the first bound: counted in it
  m.observeEditLatency(0.0015);
  m.observeEditLatency(0.010);
  m.observeEditLatency(5.0);  // beyond the last bound: +Inf only
  const std::string text = m.renderPrometheus();
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"0.001\"} 1"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"0.002\"} 2"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"0.008\"} 2"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"0.016\"} 3"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"1.024\"} 3"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_bucket{le=\"+Inf\"} 4"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_count 4"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_sum 5.0125"));
}

TEST_CASE("metrics: the etcd store's events count ownership changes, fenced rejections and append latency", "[net][metrics]") {
  Metrics m;
  const marzipan::service::EtcdEvents e = marzipan::net::etcdEventsFor(m);
  e.ownershipChanged("a", true);
  e.ownershipChanged("b", true);
  e.ownershipChanged("a", false);
  e.fencedRejection("a");
  e.appended(0.0015, 3);
  e.appended(0.003, 1);
  const std::string text = m.renderPrometheus();
  CHECK(hasLine(text, "marzipan_etcd_ownership_changes_total{change=\"gained\"} 2"));
  CHECK(hasLine(text, "marzipan_etcd_ownership_changes_total{change=\"lost\"} 1"));
  CHECK(hasLine(text, "marzipan_etcd_fenced_rejections_total 1"));
  CHECK(hasLine(text, "marzipan_etcd_append_seconds_bucket{le=\"0.002\"} 1"));
  CHECK(hasLine(text, "marzipan_etcd_append_seconds_bucket{le=\"0.005\"} 2"));
  CHECK(hasLine(text, "marzipan_etcd_append_seconds_count 2"));
  CHECK(hasLine(text, "marzipan_etcd_append_seconds_sum 0.0045"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_count 0"));
}

TEST_CASE("metrics: updates from many threads are all counted", "[net][metrics]") {
  Metrics m;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&m] {
      for (int i = 0; i < 10000; ++i) {
        m.countRequest(PathClass::staticFile);
        m.countError(500);
        m.observeEditLatency(0.004);
        m.addBytesSent(2);
      }
    });
  }
  for (std::thread& t : threads) t.join();
  const std::string text = m.renderPrometheus();
  CHECK(hasLine(text, "marzipan_http_requests_total{path=\"static\"} 40000"));
  CHECK(hasLine(text, "marzipan_errors_total{code=\"500\"} 40000"));
  CHECK(hasLine(text, "marzipan_edit_latency_seconds_count 40000"));
  CHECK(hasLine(text, "marzipan_bytes_sent_total 80000"));
}
