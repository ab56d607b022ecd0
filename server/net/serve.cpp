// `marzipan serve`: parses flags and MARZIPAN_* variables, creates the data directory, runs
// HttpServer until a signal. The default web root is MARZIPAN_DEFAULT_WEB_ROOT, which CMake
// sets to the source tree's web-client/.
#include "net/serve.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string_view>
#include <thread>

#include "net/http_server.hpp"

#ifndef MARZIPAN_DEFAULT_WEB_ROOT
#define MARZIPAN_DEFAULT_WEB_ROOT "web-client"
#endif

namespace fs = std::filesystem;

namespace marzipan::net {

namespace {

constexpr int kExitOk = 0, kExitUsage = 2;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Setting {
  std::string_view flag, env;
  std::optional<std::string> value;
};

unsigned parseUnsigned(const Setting& s, unsigned max) {
  const std::string& text = *s.value;
  unsigned v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || v > max) {
    throw UsageError(std::string(s.flag) + " (or " + std::string(s.env) + "): \"" + text + "\" is not an integer 0…" +
                     std::to_string(max));
  }
  return v;
}

bool isIpAddress(const std::string& text) {
  unsigned char buffer[16];
  return inet_pton(AF_INET, text.c_str(), buffer) == 1 || inet_pton(AF_INET6, text.c_str(), buffer) == 1;
}

int serve(const std::vector<std::string>& args, std::ostream& out) {
  Setting bind{"--bind", "MARZIPAN_BIND", {}}, port{"--port", "MARZIPAN_PORT", {}},
      threads{"--threads", "MARZIPAN_THREADS", {}}, webRoot{"--web-root", "MARZIPAN_WEB_ROOT", {}},
      dataDir{"--data-dir", "MARZIPAN_DATA_DIR", {}};
  Setting* const settings[] = {&bind, &port, &threads, &webRoot, &dataDir};

  for (Setting* s : settings) {
    const char* v = std::getenv(std::string(s->env).c_str());
    if (v && *v) s->value = v;  // set but empty = unset
  }
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      printServeUsage(out);
      return kExitOk;
    }
    const std::size_t eq = arg.find('=');
    const std::string_view name = std::string_view(arg).substr(0, eq);
    Setting* match = nullptr;
    for (Setting* s : settings) {
      if (s->flag == name) match = s;
    }
    if (!match) throw UsageError("unknown option \"" + arg + "\"");
    if (eq != std::string::npos) {
      match->value = arg.substr(eq + 1);
    } else {
      if (i + 1 == args.size()) throw UsageError(arg + " needs a value");
      match->value = args[++i];
    }
  }

  HttpServerOptions options;
  if (bind.value) {
    if (!isIpAddress(*bind.value)) throw UsageError("--bind (or MARZIPAN_BIND): \"" + *bind.value + "\" is not an IPv4 or IPv6 address");
    options.bind = *bind.value;
  }
  if (port.value) options.port = static_cast<std::uint16_t>(parseUnsigned(port, 65535));
  const unsigned threadCount = threads.value ? parseUnsigned(threads, 1024) : 0;
  options.threads = threadCount ? threadCount : std::max(1u, std::thread::hardware_concurrency());
  options.webRoot = webRoot.value ? fs::path(*webRoot.value) : fs::path(MARZIPAN_DEFAULT_WEB_ROOT);
  if (webRoot.value && webRoot.value->empty()) throw UsageError("--web-root (or MARZIPAN_WEB_ROOT) is empty");
  std::error_code ec;
  if (!fs::is_directory(options.webRoot, ec)) {
    throw std::runtime_error("web root " + options.webRoot.string() + " is not a directory; pass --web-root DIR");
  }
  if (dataDir.value) {
    if (dataDir.value->empty()) throw UsageError("--data-dir (or MARZIPAN_DATA_DIR) is empty");
    fs::create_directories(*dataDir.value, ec);
    if (ec) throw std::runtime_error("cannot create data directory " + *dataDir.value + ": " + ec.message());
  }
  options.handleSignals = true;

  HttpServer server(options);
  server.start();
  const std::string host = options.bind.find(':') != std::string::npos ? "[" + options.bind + "]" : options.bind;
  out << "listening on http://" << host << ':' << server.port() << std::endl;
  server.waitForStopRequest();
  server.stop();
  return kExitOk;
}

}  // namespace

int runServe(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  try {
    return serve(args, out);
  } catch (const UsageError& e) {
    err << "marzipan serve: " << e.what() << "\n\n";
    printServeUsage(err);
    return kExitUsage;
  }
}

void printServeUsage(std::ostream& os) {
  os << R"(Usage: marzipan serve [options]

Serves the browser client (the files of the web root) at /, /healthz (200 "ok") and /metrics
(Prometheus text) over HTTP. The WebSocket API at /ws comes with the next step of the server.

Options (each also read from the environment variable in brackets; a flag wins):
  --bind ADDR       IPv4 or IPv6 address to listen on [MARZIPAN_BIND]; default 127.0.0.1,
                    0.0.0.0 for every interface
  --port N          TCP port, 0 = pick a free one [MARZIPAN_PORT]; default 8080
  --threads N       I/O threads, 0 = one per core [MARZIPAN_THREADS]; default one per core
  --web-root DIR    directory served at / [MARZIPAN_WEB_ROOT]; default the source tree's
                    web-client/
  --data-dir DIR    where sessions will be kept, created if missing [MARZIPAN_DATA_DIR]
  --help            this text

Prints "listening on http://HOST:PORT" once it accepts connections and logs connection events
to stderr. SIGINT or SIGTERM: stops accepting, finishes the requests in flight, exits 0.
Exit status: 0 after a signal, 1 when it cannot start (web root missing, port in use),
2 usage error. Options also take the form --name=value.
)";
}

}  // namespace marzipan::net
