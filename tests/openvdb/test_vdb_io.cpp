// .vdb export and import (built with -DMARZIPAN_WITH_OPENVDB=ON): the file is read back with
// OpenVDB itself and every voxel of the domain compared with the volume's, within 1e-4 vu.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <sstream>

#include <openvdb/openvdb.h>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/openvdb/vdb_io.hpp"
#include "engine/solids.hpp"

using namespace marzipan;

namespace {

std::string scratch(const char* name) {
  return (std::filesystem::temp_directory_path() / (std::string("marzipan-test-") + name)).string();
}

}  // namespace

TEST_CASE("a saved .vdb holds the volume's distances as a level set", "[openvdb]") {
  const Volume pig = makeSolid(SolidKind::Pig, {72, 64, 56});
  const std::string path = scratch("pig.vdb");
  saveVdb(pig, path);

  openvdb::io::File file(path);
  file.open();
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
  file.close();
  REQUIRE(grid);
  CHECK(grid->getGridClass() == openvdb::GRID_LEVEL_SET);
  CHECK(grid->voxelSize()[0] == Approx(1.0));
  CHECK(grid->background() == pig.band());
  auto acc = grid->getConstAccessor();
  double worst = 0;
  std::size_t active = 0, band = 0;
  const Int3 d = pig.dims();
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        const float v = pig.at(x, y, z);
        worst = std::max(worst, double(std::fabs(acc.getValue(openvdb::Coord(x, y, z)) - v)));
        band += std::fabs(v) < pig.band() ? 1 : 0;
        active += acc.isValueOn(openvdb::Coord(x, y, z)) ? 1 : 0;
      }
  INFO("worst difference " << worst << " vu over " << band << " band voxels");
  CHECK(worst <= 1e-4);
  CHECK(active == band);
  CHECK(band > 10000);

  const Volume back = loadVdb(path, d);
  double worstBack = 0;
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) worstBack = std::max(worstBack, double(std::fabs(back.at(x, y, z) - pig.at(x, y, z))));
  CHECK(worstBack <= 1e-4);
  std::filesystem::remove(path);
}

TEST_CASE("unreadable .vdb files are refused", "[openvdb][errors]") {
  const std::string path = scratch("junk.vdb");
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    std::fputs("not a vdb file", f);
    std::fclose(f);
  }
  CHECK_THROWS_AS(loadVdb(path, {16, 16, 16}), EngineError);
  CHECK_THROWS_AS(loadVdb(scratch("missing.vdb"), {16, 16, 16}), EngineError);
  std::filesystem::remove(path);
}

TEST_CASE("the stream forms write and read the same level set as the files, in memory", "[openvdb]") {
  const Volume pig = makeSolid(SolidKind::Pig, {72, 64, 56});
  std::stringstream stream(std::ios::in | std::ios::out | std::ios::binary);
  saveVdb(pig, stream);
  const std::string bytes = stream.str();
  CHECK(bytes.substr(0, 4) == std::string("\x20\x42\x44\x56", 4));  // OpenVDB's magic, little-endian
  std::istringstream in(bytes, std::ios::binary);
  const Volume back = loadVdb(in, pig.dims());
  double worst = 0;
  const Int3 d = pig.dims();
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) worst = std::max(worst, double(std::fabs(back.at(x, y, z) - pig.at(x, y, z))));
  CHECK(worst == 0.0);
  CHECK(digest(back) == digest(pig));

  // Every prefix that ends inside the file is refused (header, metadata, topology or values).
  for (const std::size_t keep : {std::size_t(0), std::size_t(8), std::size_t(56), std::size_t(200), bytes.size() / 2,
                                 bytes.size() - 1}) {
    INFO(keep);
    std::istringstream cut(bytes.substr(0, keep), std::ios::binary);
    CHECK_THROWS_AS(loadVdb(cut, pig.dims()), EngineError);
  }
  // A grid that reaches outside a smaller domain is refused before any copy.
  std::istringstream again(bytes, std::ios::binary);
  CHECK_THROWS_AS(loadVdb(again, {32, 32, 32}), EngineError);
}
