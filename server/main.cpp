// The `marzipan` executable: one binary, one subcommand per mode of use. Each subcommand
// owns its flags and its usage text; this file only picks one and turns exceptions that
// escaped it into an exit status.
#include <exception>
#include <iostream>
#include <string>
#include <string_view>
#include <vector>

#include "net/healthcheck.hpp"
#include "net/serve.hpp"
#include "service/batch.hpp"

namespace {

struct Command {
  std::string_view name;
  std::string_view summary;
  int (*run)(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
};

constexpr Command kCommands[] = {
    {"batch", "apply operations from a JSON-lines file offline; write a mesh, volume or image",
     marzipan::service::runBatch},
    {"healthcheck", "exit 0 when a running server answers GET /healthz with 200 \"ok\" (containers)",
     marzipan::net::runHealthcheck},
    {"serve", "serve the browser client and the sculpting API (WebSocket /ws) until SIGINT/SIGTERM",
     marzipan::net::runServe},
};

void printUsage(std::ostream& os) {
  os << "Usage: marzipan COMMAND [options]\n\nCommands:\n";
  for (const Command& c : kCommands) os << "  " << c.name << std::string(13 - c.name.size(), ' ') << c.summary << '\n';
  os << "\n`marzipan COMMAND --help` describes a command.\n";
}

}  // namespace

int main(int argc, char** argv) {
  using marzipan::service::kExitBadInput;
  using marzipan::service::kExitOk;
  using marzipan::service::kExitUsage;
  if (argc < 2) {
    printUsage(std::cerr);
    return kExitUsage;
  }
  const std::string_view first = argv[1];
  if (first == "--help" || first == "-h" || first == "help") {
    printUsage(std::cout);
    return kExitOk;
  }
  for (const Command& c : kCommands) {
    if (c.name != first) continue;
    try {
      return c.run(std::vector<std::string>(argv + 2, argv + argc), std::cout, std::cerr);
    } catch (const std::exception& e) {
      std::cerr << "marzipan " << c.name << ": " << e.what() << '\n';
      return kExitBadInput;
    }
  }
  std::cerr << "marzipan: unknown command \"" << first << "\"\n\n";
  printUsage(std::cerr);
  return kExitUsage;
}
