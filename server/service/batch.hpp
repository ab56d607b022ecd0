// `marzipan batch`: runs a file of operation objects (protocol/cpp/ops.hpp, one per line) on a
// solid offline, through the same applyOp the server uses, then writes a mesh, a volume file
// or a rendered image, and reports measures as JSON lines.
//
// Conventions: arguments are the ones after "batch"; results go to `out` (stats lines), every
// diagnostic to `err` as "FILE:LINE: reason" or "marzipan batch: reason". Output files are
// written only after every operation succeeded. Exit status: 0 success, 1 bad input (an
// unreadable or invalid ops line, file, or an operation the engine refuses), 2 usage error.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace marzipan::service {

inline constexpr int kExitOk = 0, kExitBadInput = 1, kExitUsage = 2;

int runBatch(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
void printBatchUsage(std::ostream& os);

}  // namespace marzipan::service
