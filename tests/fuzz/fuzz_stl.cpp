// Fuzz target: STL files, binary and ASCII (server/engine/mesh_io.hpp, parseStl), then the
// import of what parses (engine_checks.hpp). Binary STL is chosen by the exact size
// 84 + 50 * count, so the seeds hold both kinds.
#include <cstddef>
#include <cstdint>

#include "engine_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    marzipan::fuzz::expectSoundMesh(marzipan::parseStl(marzipan::fuzz::bytesOf(data, size)));
  } catch (const marzipan::EngineError& e) {
    marzipan::fuzz::expectFormatError(e);
  }
  return 0;
}
