// `marzipan healthcheck`: asks a running `marzipan serve` for GET /healthz and turns the answer
// into an exit status, so that container health checks need no curl in the image. Plain POSIX
// sockets on purpose: the check is a dozen system calls, and Beast would cost the build far more
// than it saves here.
//
// Conventions: healthy means status 200 and the body exactly "ok". The whole exchange (name
// lookup aside, which is the system resolver's) must finish within the timeout. Exit 0 healthy,
// 1 not healthy (one line on stderr says why), 2 usage error, like the other subcommands.
#pragma once

#include <chrono>
#include <ostream>
#include <string>
#include <vector>

namespace marzipan::net {

inline constexpr std::chrono::milliseconds kHealthcheckTimeout{2'000};

struct HealthResult {
  bool healthy = false;
  std::string detail;  // one line: the status and body, or why no answer came
};

// GET `url` ("http://HOST[:PORT][/PATH]", HOST an IPv4 address, a name or "[IPv6]"; PORT 80 when
// left out, PATH "/" when left out) and judge the answer. Throws std::invalid_argument for a URL
// it cannot take; every network failure is an unhealthy result instead.
HealthResult probeHealth(const std::string& url, std::chrono::milliseconds timeout = kHealthcheckTimeout);

// The URL the check asks when none is given: /healthz at MARZIPAN_BIND (127.0.0.1 when unset;
// the wildcards 0.0.0.0 and :: become the loopback address of their family) and MARZIPAN_PORT
// (8080 when unset), the same variables `marzipan serve` reads. Throws std::invalid_argument when
// MARZIPAN_PORT is not a port 1…65535.
std::string defaultHealthUrl();

int runHealthcheck(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
void printHealthcheckUsage(std::ostream& os);

}  // namespace marzipan::net
