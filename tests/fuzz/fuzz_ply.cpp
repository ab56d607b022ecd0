// Fuzz target: binary little-endian PLY (server/engine/mesh_io.hpp, parsePly), then the import
// of what parses (engine_checks.hpp).
#include <cstddef>
#include <cstdint>

#include "engine_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    marzipan::fuzz::expectSoundMesh(marzipan::parsePly(marzipan::fuzz::bytesOf(data, size)));
  } catch (const marzipan::EngineError& e) {
    marzipan::fuzz::expectFormatError(e);
  }
  return 0;
}
