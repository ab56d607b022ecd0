// A .vdb "decompression bomb" (issue 31 item 7): a grid with an empty tree and background 0 is a
// few hundred bytes and has no active voxels to check against the domain, yet every voxel of
// the domain reads as 0, a value inside the band, so every brick becomes data. A client's upload
// is read with the session's max_volume_bytes (loadVdb's maxBytes): the read stops once its
// bricks pass it instead of building the whole domain first.
#include <catch2/catch.hpp>

#include <cstdint>
#include <fstream>
#include <limits>
#include <optional>
#include <span>
#include <sstream>
#include <string>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include "engine/errors.hpp"
#include "engine/openvdb/vdb_io.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

namespace {

// A level-set grid named "surface" with nothing in its tree, as a stream (what volume.save writes).
std::string emptyGrid(float background) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(background);
  grid->setName("surface");
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  std::ostringstream out(std::ios::binary);
  openvdb::io::Stream(out).write({grid});
  return std::move(out).str();
}

std::span<const std::uint8_t> bytesOf(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// This process's resident and peak resident memory in bytes (/proc/self/status).
std::size_t statusBytes(const std::string& key) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind(key + ":", 0) == 0) return std::stoull(line.substr(key.size() + 1)) * 1024;
  return 0;
}

// Makes the peak resident memory the current one (Linux 4.0 and later).
bool resetPeak() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return bool(clear);
}

// The error loadVdb refuses the file with, none when it accepts it.
std::optional<EngineError> refusal(const std::string& file, Int3 dims, std::size_t maxBytes) {
  try {
    loadVdb(bytesOf(file), dims, Volume::kDefaultBand, maxBytes);
    return std::nullopt;
  } catch (const EngineError& e) {
    return e;
  }
}

}  // namespace

TEST_CASE(".vdb bomb: an empty tree of background 0 stops at the volume limit, not at the domain", "[openvdb]") {
  const std::string bomb = emptyGrid(0.0f);
  const Int3 dims{256, 256, 256};
  INFO(bomb.size() << " bytes");
  CHECK(bomb.size() < 1024);
  // What it is without a limit (a file read by `marzipan batch`): every brick of the domain.
  {
    const Volume whole = loadVdb(bytesOf(bomb), dims);
    CHECK(whole.presentBricks() == std::size_t(32 * 32 * 32));
    CHECK(whole.memoryBytes() > (std::size_t(64) << 20));
  }
  // With a client's limit: refused once past 8 MiB of bricks, with at most one slab of bricks
  // (32 x 32 of them, ~2 MiB here) and the slab's values (2 MiB) beyond it ever held.
  const std::size_t limit = std::size_t(8) << 20;
  REQUIRE(resetPeak());
  const std::size_t before = statusBytes("VmRSS");
  const std::optional<EngineError> e = refusal(bomb, dims, limit);
  const std::size_t peak = statusBytes("VmHWM") - before;
  INFO("peak +" << peak / 1024 << " KiB");
  CHECK(peak < limit + (std::size_t(8) << 20));
  REQUIRE(e);
  INFO(e->what());
  CHECK(e->kind() == ErrorKind::TooLarge);
  CHECK(e->field() == "file");
}

TEST_CASE(".vdb limit: a volume of exactly maxBytes loads, one byte less refuses it", "[openvdb]") {
  const Volume pig = makeSolid(SolidKind::Pig, {96, 80, 72});
  std::ostringstream out(std::ios::binary);
  saveVdb(pig, out);
  const std::string file = std::move(out).str();
  const Volume back = loadVdb(bytesOf(file), pig.dims(), pig.band(), pig.memoryBytes());
  CHECK(back.memoryBytes() == pig.memoryBytes());
  CHECK(back.presentBricks() == pig.presentBricks());
  const std::optional<EngineError> under = refusal(file, pig.dims(), pig.memoryBytes() - 1);
  REQUIRE(under);
  CHECK(under->kind() == ErrorKind::TooLarge);
  // A background of the band (what every writer of a level set uses) stores nothing.
  const Volume outside = loadVdb(bytesOf(emptyGrid(Volume::kDefaultBand)), {256, 256, 256}, Volume::kDefaultBand,
                                 std::size_t(1) << 20);
  CHECK(outside.presentBricks() == 0);
}
