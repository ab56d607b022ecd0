// Fuzz target: the native volume file (server/engine/volume_file.hpp, loadVolume). Each input
// is loaded as it is and, so that mutations get past the checksum to the checks behind it,
// once more with its trailer set to the right CRC-32. A file that loads must be sound
// (engine_checks.hpp) and save back to the very same bytes.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/little_endian.hpp"
#include "engine/measures.hpp"
#include "engine/volume_file.hpp"
#include "engine_checks.hpp"

using namespace marzipan;
using marzipan::fuzz::expect;

namespace {

void load(std::span<const std::uint8_t> bytes) {
  try {
    const Volume vol = loadVolume(bytes);
    fuzz::expectSoundVolume(vol);
    const std::vector<std::uint8_t> saved = saveVolume(vol);
    expect(saved.size() == savedVolumeSize(vol), "savedVolumeSize is the saved size");
    expect(std::equal(saved.begin(), saved.end(), bytes.begin(), bytes.end()), "a loaded file saves to the same bytes");
    expect(digest(loadVolume(saved)) == digest(vol), "loading preserves the digest");
  } catch (const EngineError& e) {
    fuzz::expectFormatError(e);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  load(fuzz::bytesOf(data, size));
  if (size < kVolumeFileHeaderBytes + kVolumeFileTrailerBytes) return 0;
  std::vector<std::uint8_t> sealed(data, data + size);
  const std::size_t body = size - kVolumeFileTrailerBytes;
  le::put32(sealed.data() + body, crc32Ieee({sealed.data(), body}));
  load(sealed);
  return 0;
}
