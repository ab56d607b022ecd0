// `marzipan serve`: the flags and environment of the server, then HttpServer until SIGINT or
// SIGTERM. Beast-free; the sockets are behind HttpServer (http_server.hpp).
//
// Conventions: arguments are the ones after "serve"; "listening on http://HOST:PORT" goes to
// `out` (flushed) once connections are accepted; diagnostics to `err` as "marzipan serve: reason",
// connection events to stderr. Each flag may come from an environment variable MARZIPAN_* (an
// empty one counts as unset); a flag wins. Exit status: 0 after a signal, 1 when the server
// cannot start (thrown as std::runtime_error, reported by main), 2 usage error.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace marzipan::net {

int runServe(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
void printServeUsage(std::ostream& os);

}  // namespace marzipan::net
