// http_server: an in-process HttpServer on 127.0.0.1, port 0, over a scratch web root, driven
// by the plain-socket client of support.hpp. Every receive times out after 5 s.
#include <catch2/catch.hpp>

#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "net/http_server.hpp"
#include "support.hpp"

using marzipan::net::HttpServer;
using marzipan::net::HttpServerOptions;
using marzipan::test::Connection;
using marzipan::test::request;
namespace fs = std::filesystem;

namespace {

const std::string kIndex = "<!DOCTYPE html><title>t</title>";

// A server over a fresh web root; log lines are kept for inspection.
struct Fixture {
  explicit Fixture(const std::string& name) {
    const fs::path dir = marzipan::test::scratch(name);
    fs::create_directories(dir / "root" / "js");
    marzipan::test::writeText(dir / "root" / "index.html", kIndex);
    marzipan::test::writeText(dir / "root" / "js" / "app.mjs", "export const x = 1;\n");
    marzipan::test::writeText(dir / "secret.txt", "secret");
    HttpServerOptions options;
    options.port = 0;
    options.webRoot = dir / "root";
    options.threads = 2;
    options.log = [this](const std::string& line) {
      const std::lock_guard lock(mutex);
      log.push_back(line);
    };
    server.emplace(options);
    server->start();
    port = server->port();
  }

  std::mutex mutex;
  std::vector<std::string> log;
  std::optional<HttpServer> server;
  std::uint16_t port = 0;
};

}  // namespace

TEST_CASE("http server: healthz, metrics, static files, refusals, methods", "[net][http]") {
  Fixture f("http-basic");
  REQUIRE(f.port != 0);

  const auto health = request(f.port, "GET", "/healthz");
  CHECK(health.status == 200);
  CHECK(health.body == "ok");

  const auto index = request(f.port, "GET", "/");
  CHECK(index.status == 200);
  CHECK(index.headers.at("content-type") == "text/html; charset=utf-8");
  CHECK(index.headers.at("content-length") == std::to_string(kIndex.size()));
  CHECK(index.body == kIndex);
  CHECK(request(f.port, "GET", "/index.html").body == kIndex);

  const auto module = request(f.port, "GET", "/js/app.mjs");
  CHECK(module.status == 200);
  CHECK(module.headers.at("content-type") == "text/javascript; charset=utf-8");

  const auto head = request(f.port, "HEAD", "/index.html");
  CHECK(head.status == 200);
  CHECK(head.headers.at("content-length") == std::to_string(kIndex.size()));
  CHECK(head.body.empty());

  CHECK(request(f.port, "GET", "/missing.html").status == 404);
  CHECK(request(f.port, "GET", "/ws").status == 404);
  for (const char* target : {"/../secret.txt", "/../etc/passwd", "/%2e%2e/", "/%2e%2e/secret.txt", "/js/..%2fapp.mjs",
                             "/%5c..%5csecret.txt", "/.%2e/secret.txt"}) {
    INFO(target);
    const int status = request(f.port, "GET", target).status;
    CHECK((status == 403 || status == 400));
  }

  const auto post = request(f.port, "POST", "/index.html");
  CHECK(post.status == 405);
  CHECK(post.headers.at("allow") == "GET, HEAD");
  CHECK(request(f.port, "DELETE", "/").status == 405);

  const auto metrics = request(f.port, "GET", "/metrics");
  CHECK(metrics.status == 200);
  CHECK(metrics.headers.at("content-type").rfind("text/plain; version=0.0.4", 0) == 0);
  for (const char* name : {"marzipan_http_requests_total{path=\"healthz\"} 1", "marzipan_http_requests_total{path=\"metrics\"} 1",
                           "marzipan_errors_total{code=\"404\"}", "marzipan_errors_total{code=\"405\"} 2",
                           "marzipan_sessions 0", "marzipan_clients 0", "marzipan_edit_latency_seconds_bucket",
                           "marzipan_bytes_sent_total"}) {
    INFO(name);
    CHECK(metrics.body.find(name) != std::string::npos);
  }

  // Promptly, with room for a loaded machine: nothing is open.
  const auto start = std::chrono::steady_clock::now();
  f.server->stop();
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(10));
  const std::lock_guard lock(f.mutex);
  CHECK(f.log.size() >= 2);
  CHECK(f.log.front().rfind("http: accept 127.0.0.1:", 0) == 0);
}

TEST_CASE("http server: keep-alive serves several requests on one connection", "[net][http]") {
  Fixture f("http-keepalive");
  Connection c(f.port);
  c.send("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\nGET /index.html HTTP/1.1\r\nHost: x\r\n\r\n");
  CHECK(c.receive().body == "ok");
  CHECK(c.receive().body == kIndex);
  c.send("GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  const auto last = c.receive();
  CHECK(last.body == "ok");
  CHECK(last.headers.at("connection") == "close");
  CHECK(c.closedByPeer());
}

TEST_CASE("http server: oversized headers get 431, oversized bodies 413, then a close", "[net][http]") {
  Fixture f("http-limits");
  Connection big(f.port);
  big.send("GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n");
  CHECK(big.receive().status == 431);
  CHECK(big.closedByPeer());

  Connection body(f.port);
  body.send("GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n");
  CHECK(body.receive().status == 413);
  CHECK(body.closedByPeer());

  Connection small(f.port);
  small.send("GET /healthz HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello");
  CHECK(small.receive().body == "ok");
}

TEST_CASE("http server: stop() closes idle keep-alive connections and returns promptly", "[net][http]") {
  Fixture f("http-stop");
  Connection idle(f.port);
  idle.send("GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n");
  REQUIRE(idle.receive().body == "ok");
  // Promptly: not after the idle connection's timeout (idleTimeout, 30 s), with room for a loaded
  // machine.
  const auto start = std::chrono::steady_clock::now();
  f.server->stop();
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(10));
  CHECK(idle.closedByPeer());
  f.server->stop();  // idempotent
  CHECK_THROWS(Connection(f.port));
}

TEST_CASE("http server: start() reports a port in use and a bad web root", "[net][http]") {
  Fixture f("http-errors");
  HttpServerOptions same;
  same.port = f.port;
  same.webRoot = marzipan::test::scratch("http-errors-root");
  same.log = [](const std::string&) {};
  HttpServer second(same);
  CHECK_THROWS_WITH(second.start(), Catch::Contains("cannot listen on 127.0.0.1:"));

  HttpServerOptions noRoot = same;
  noRoot.port = 0;
  noRoot.webRoot = same.webRoot / "missing";
  HttpServer third(noRoot);
  CHECK_THROWS_WITH(third.start(), Catch::Contains("is not a directory"));
}
