// Fuzz target: Wavefront OBJ text (server/engine/mesh_io.hpp, parseObj), then the import of
// what parses (engine_checks.hpp).
#include <cstddef>
#include <cstdint>

#include "engine_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    marzipan::fuzz::expectSoundMesh(marzipan::parseObj(marzipan::fuzz::textOf(data, size)));
  } catch (const marzipan::EngineError& e) {
    marzipan::fuzz::expectFormatError(e);
  }
  return 0;
}
