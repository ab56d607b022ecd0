// healthcheck: probeHealth and `marzipan healthcheck` against an in-process HttpServer on
// 127.0.0.1 (port 0), a closed port, a listener that never answers, and a raw socket that answers
// whatever a case gives it. The one slow case waits out the 2 s timeout.
#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "net/healthcheck.hpp"
#include "net/http_server.hpp"
#include "support.hpp"
#include "test_paths.hpp"

using marzipan::net::defaultHealthUrl;
using marzipan::net::HttpServer;
using marzipan::net::HttpServerOptions;
using marzipan::net::probeHealth;
using marzipan::net::runHealthcheck;
namespace fs = std::filesystem;

namespace {

struct Server {
  explicit Server(const std::string& name) {
    const fs::path dir = marzipan::test::scratch(name);
    marzipan::test::writeText(dir / "index.html", "<!DOCTYPE html>");
    HttpServerOptions options;
    options.port = 0;
    options.webRoot = dir;
    options.log = [](const std::string&) {};
    server.emplace(options);
    server->start();
    base = "http://127.0.0.1:" + std::to_string(server->port());
  }
  std::optional<HttpServer> server;
  std::string base;
};

// A listening socket on 127.0.0.1 with a free port; closed when destroyed.
class Listener {
 public:
  Listener() : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd_, 4) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
      throw std::runtime_error("cannot listen on loopback");
    }
    port_ = ntohs(addr.sin_port);
  }
  ~Listener() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  int fd() const { return fd_; }
  std::uint16_t port() const { return port_; }

 private:
  int fd_;
  std::uint16_t port_ = 0;
};

// Accepts one connection, reads the request, sends `answer` and closes.
marzipan::net::HealthResult probeRaw(const std::string& answer) {
  Listener listener;
  std::thread peer([&] {
    const int c = ::accept(listener.fd(), nullptr, nullptr);
    if (c < 0) return;
    char buffer[1024];
    (void)::recv(c, buffer, sizeof buffer, 0);
    (void)::send(c, answer.data(), answer.size(), MSG_NOSIGNAL);
    ::close(c);
  });
  const auto r = probeHealth("http://127.0.0.1:" + std::to_string(listener.port()) + "/healthz");
  peer.join();
  return r;
}

// Sets an environment variable for one scope, restoring the old value.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) ::setenv(name, value, 1);
    else ::unsetenv(name);
  }
  ~ScopedEnv() {
    if (old_) ::setenv(name_, old_->c_str(), 1);
    else ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

int run(std::vector<std::string> args, std::string* errText = nullptr) {
  std::ostringstream out, err;
  const int status = runHealthcheck(args, out, err);
  if (errText) *errText = err.str();
  return status;
}

}  // namespace

TEST_CASE("healthcheck: a serving server is healthy, other answers are not", "[net][healthcheck]") {
  Server s("healthcheck-serving");
  const auto ok = probeHealth(s.base + "/healthz");
  CHECK(ok.healthy);
  CHECK(ok.detail == "status 200, body \"ok\"");

  const auto missing = probeHealth(s.base + "/nothing-here");
  CHECK_FALSE(missing.healthy);
  CHECK(missing.detail.starts_with("status 404"));
  // 200, but not the health answer.
  CHECK_FALSE(probeHealth(s.base + "/").healthy);
  CHECK_FALSE(probeHealth(s.base).healthy);

  CHECK(run({"--url", s.base + "/healthz"}) == 0);
  CHECK(run({"--url=" + s.base + "/healthz"}) == 0);
  std::string err;
  CHECK(run({"--url", s.base + "/missing"}, &err) == 1);
  CHECK(err.find("status 404") != std::string::npos);
}

TEST_CASE("healthcheck: default URL from MARZIPAN_BIND and MARZIPAN_PORT", "[net][healthcheck]") {
  {
    const ScopedEnv bind("MARZIPAN_BIND", nullptr), port("MARZIPAN_PORT", nullptr);
    CHECK(defaultHealthUrl() == "http://127.0.0.1:8080/healthz");
  }
  {
    const ScopedEnv bind("MARZIPAN_BIND", "0.0.0.0"), port("MARZIPAN_PORT", "9000");
    CHECK(defaultHealthUrl() == "http://127.0.0.1:9000/healthz");
  }
  {
    const ScopedEnv bind("MARZIPAN_BIND", "::"), port("MARZIPAN_PORT", "");
    CHECK(defaultHealthUrl() == "http://[::1]:8080/healthz");
  }
  {
    const ScopedEnv bind("MARZIPAN_BIND", "10.1.2.3"), port("MARZIPAN_PORT", "0");
    CHECK_THROWS_AS(defaultHealthUrl(), std::invalid_argument);
    CHECK(run({}) == 2);
  }
  Server s("healthcheck-env");
  const ScopedEnv bind("MARZIPAN_BIND", "0.0.0.0"),
      port("MARZIPAN_PORT", s.base.substr(s.base.rfind(':') + 1).c_str());
  CHECK(run({}) == 0);
}

TEST_CASE("healthcheck: no server, a silent server, a stopped server", "[net][healthcheck]") {
  std::uint16_t closedPort;
  {
    Listener l;
    closedPort = l.port();
  }
  const auto refused = probeHealth("http://127.0.0.1:" + std::to_string(closedPort) + "/healthz");
  CHECK_FALSE(refused.healthy);
  CHECK(refused.detail.find("refused") != std::string::npos);

  // Accepted by the kernel's backlog, never answered: the check gives up after its 2 s (the
  // upper bound leaves room for a loaded machine; the message names the 2 s).
  Listener silent;
  const auto start = std::chrono::steady_clock::now();
  std::string err;
  CHECK(run({"--url", "http://127.0.0.1:" + std::to_string(silent.port()) + "/healthz"}, &err) == 1);
  const auto elapsed = std::chrono::steady_clock::now() - start;
  CHECK(elapsed >= std::chrono::milliseconds(1900));
  CHECK(elapsed < std::chrono::milliseconds(10000));
  CHECK(err.find("within 2000 ms") != std::string::npos);

  Server s("healthcheck-stopped");
  CHECK(probeHealth(s.base + "/healthz").healthy);
  s.server->stop();
  CHECK_FALSE(probeHealth(s.base + "/healthz").healthy);
}

TEST_CASE("healthcheck: answers are read by Content-Length, or to the end", "[net][healthcheck]") {
  CHECK(probeRaw("HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok").healthy);
  CHECK(probeRaw("HTTP/1.0 200 OK\r\ncontent-length:  2 \r\n\r\nokay").healthy);
  CHECK(probeRaw("HTTP/1.1 200 OK\r\nConnection: close\r\n\r\nok").healthy);
  CHECK_FALSE(probeRaw("HTTP/1.1 200 OK\r\nContent-Length: 3\r\n\r\nok!").healthy);
  CHECK_FALSE(probeRaw("HTTP/1.1 503 Service Unavailable\r\nContent-Length: 2\r\n\r\nok").healthy);
  const auto cut = probeRaw("HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\no");
  CHECK_FALSE(cut.healthy);
  CHECK(cut.detail == "connection closed before the whole body");
  CHECK_FALSE(probeRaw("SSH-2.0-OpenSSH\r\n\r\n").healthy);
  CHECK_FALSE(probeRaw("HTTP/1.1 200 OK\r\n").healthy);
  CHECK_FALSE(probeRaw("").healthy);
}

TEST_CASE("healthcheck: usage errors exit 2", "[net][healthcheck]") {
  for (const char* url : {"https://127.0.0.1/healthz", "127.0.0.1:8080", "http://:8080/", "http://h:0/",
                          "http://h:99999/", "http://h:x/", "http://[::1/", "http://[::1]x/", "http://h/a b"}) {
    INFO(url);
    CHECK_THROWS_AS(probeHealth(url), std::invalid_argument);
    CHECK(run({"--url", url}) == 2);
  }
  CHECK(run({"--bogus"}) == 2);
  CHECK(run({"--url"}) == 2);
  CHECK(run({"--help"}) == 0);
}

TEST_CASE("marzipan healthcheck: the subcommand of the built binary", "[net][healthcheck][cli]") {
  Server s("healthcheck-cli");
  const auto status = [](const std::string& args) {
    const int raw = std::system((std::string("'") + marzipan::test_paths::kCli + "' healthcheck " + args + " >/dev/null 2>&1").c_str());
    return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  };
  CHECK(status("--url " + s.base + "/healthz") == 0);
  CHECK(status("--url " + s.base + "/missing") == 1);
  CHECK(status("--nonsense") == 2);
}
