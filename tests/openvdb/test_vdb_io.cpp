// .vdb export and import (built with -DMARZIPAN_WITH_OPENVDB=ON): the file is read back with
// OpenVDB itself and every voxel of the domain compared with the volume's, within 1e-4 vu.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

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

namespace {

std::string streamBytes(const openvdb::GridPtrVec& grids) {
  std::ostringstream out(std::ios::binary);
  openvdb::io::Stream(out).write(grids);
  return std::move(out).str();
}

// io::File's layout, with grid offsets, as VFX tools write it.
std::string fileBytes(const openvdb::GridPtrVec& grids, const char* name) {
  const std::string path = scratch(name);
  openvdb::io::File file(path);
  file.write(grids);
  file.close();
  std::ifstream in(path, std::ios::binary);
  std::string s{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::filesystem::remove(path);
  return s;
}

void putU32(std::string& s, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s[at + std::size_t(i)] = char(v >> (8 * i));
}

std::uint64_t getU64(const std::string& s, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = v << 8 | std::uint8_t(s[at + std::size_t(i)]);
  return v;
}

}  // namespace

// Files from other tools hold several grids (a velocity beside the surface); OpenVDB's stream
// reader would read every one, trusting each name's declared length before its bytes, so only the
// grid that is used may reach it.
TEST_CASE("a .vdb upload of several grids gives its first float grid, and later grids are never parsed", "[openvdb][errors]") {
  openvdb::initialize();
  const Volume pig = makeSolid(SolidKind::Pig, {72, 64, 56});
  std::stringstream one(std::ios::in | std::ios::out | std::ios::binary);
  saveVdb(pig, one);
  openvdb::GridPtrVecPtr read = openvdb::io::Stream(one, false).getGrids();
  const openvdb::GridBase::Ptr surface = read->front();
  auto velocity = openvdb::Vec3SGrid::create();
  velocity->setName("velocity");
  velocity->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1, 0, 0));
  const auto loads = [&](const std::string& bytes) {
    std::istringstream in(bytes, std::ios::binary);
    return digest(loadVdb(in, pig.dims()));
  };
  const auto refusal = [&](const std::string& bytes) {
    std::istringstream in(bytes, std::ios::binary);
    try {
      loadVdb(in, pig.dims());
    } catch (const EngineError& e) {
      return std::string(e.what());
    }
    return std::string("loaded");
  };

  CHECK(loads(fileBytes({velocity, surface}, "two.vdb")) == digest(pig));
  CHECK(loads(streamBytes({surface, velocity})) == digest(pig));
  CHECK_THAT(refusal(streamBytes({velocity, surface})), Catch::Contains("its first grid holds Tree_vec3s"));

  // A stream of one good grid that goes on to declare a second whose name is 2 GiB long: the
  // grid count says 2, the bytes after the first grid are a descriptor no memory should be sized
  // from. The first grid loads; OpenVDB never sees the second.
  std::string tail = streamBytes({surface});
  const std::size_t countAt = 57 + 4;  // header, then the file's metadata (no entries)
  REQUIRE(tail.substr(57, 4) == std::string(4, '\0'));
  putU32(tail, countAt, 2);
  for (const std::uint32_t w : {0x7FFFFFF0u, 0u, 0u}) {
    tail.append(4, '\0');
    putU32(tail, tail.size() - 4, w);
  }
  tail.append(64, '\0');
  CHECK(loads(tail) == digest(pig));

  // With offsets the walk reads the first grid's end and the next descriptor there, so a lie in
  // either is refused before OpenVDB reads anything.
  std::string two = fileBytes({velocity, surface}, "two-hostile.vdb");
  const std::size_t first = 57 + 4 + 4;  // header, metadata count 0, grid count
  const std::size_t nameLen = 4 + std::string("velocity").size();
  const std::size_t typeLen = 4 + std::string(openvdb::Vec3SGrid::gridType()).size();
  const std::size_t endAt = first + nameLen + typeLen + 4 + 16;
  const std::uint64_t second = getU64(two, endAt);
  REQUIRE(second > endAt);
  REQUIRE(second < two.size());
  std::string hugeName = two;
  putU32(hugeName, std::size_t(second), 0x7FFFFFF0u);
  CHECK_THAT(refusal(hugeName), Catch::Contains("a name declares 2147483632 bytes"));
  std::string badEnd = two;
  putU32(badEnd, endAt, std::uint32_t(two.size() + 1));
  CHECK_THAT(refusal(badEnd), Catch::Contains("end offset lies outside the file"));
}
