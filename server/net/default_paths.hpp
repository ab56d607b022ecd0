// Where `marzipan serve` finds the browser client and the protocol's JavaScript module when no
// flag or variable names them: the source tree it was built from. Defined in a file CMake
// generates in the build tree (server/CMakeLists.txt), not as compile definitions, so that no
// other object's compiler command line holds an absolute path: ccache then reuses every object
// for a clone of the sources at another path, and only that one small file is compiled again.
#pragma once

namespace marzipan::net {

extern const char* const kDefaultWebRoot;
extern const char* const kDefaultProtocolJs;

}  // namespace marzipan::net
