// Paths the suites read or write, all absolute: the built `marzipan`, scratch directories of
// the build tree, files of the source tree. Defined in a file CMake generates in the build tree
// (tests/CMakeLists.txt), not as compile definitions, so that no test object's compiler command
// line holds an absolute path: ccache then reuses every object for a clone at another path, and
// only that one small file is compiled again.
#pragma once

namespace marzipan::test_paths {

extern const char* const kCli;              // the built `marzipan` executable
extern const char* const kCliWorkdir;       // scratch directory of the cli suite
extern const char* const kNetWorkdir;       // scratch directory of the net suite
extern const char* const kEngineArtifacts;  // pictures the engine suite leaves for a person
extern const char* const kProtocolVectors;  // tests/protocol/vectors/vectors.json
extern const char* const kToolRegistry;     // protocol/registry/tools.json
extern const char* const kFuzzRegressions;  // tests/fuzz/regressions (inputs that broke a reader)

}  // namespace marzipan::test_paths
