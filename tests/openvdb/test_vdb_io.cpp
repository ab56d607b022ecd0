// .vdb export and import (built with -DMARZIPAN_WITH_OPENVDB=ON): the file is read back with
// OpenVDB itself and every voxel of the domain compared with the volume's, within 1e-4 vu.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include "engine/color_space.hpp"
#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/measures.hpp"
#include "engine/openvdb/vdb_io.hpp"
#include "engine/solids.hpp"
#include "engine/support.hpp"

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

namespace {

// The pig with colours that are a function of the voxel, some of them the base colour, and a
// mask that the file does not keep.
Volume paintedPig() {
  Volume pig = makeSolid(SolidKind::Pig, {72, 64, 56});
  test::paintBricks(pig, [](Int3 b, int i) {
    const Int3 p = Bricks::origin(b) + Bricks::local(i);
    if (p.z < 20) return texelOf(kClayColor);
    return Texel{std::uint8_t(3 * p.x), std::uint8_t(255 - 3 * p.y), std::uint8_t(p.x * p.y % 256), 0};
  });
  return pig;
}

// Every voxel's channels.
std::vector<Texel> texels(const Volume& v) {
  std::vector<Texel> t(std::size_t(v.domain().voxels()));
  v.gatherTexels(v.domain(), t.data());
  return t;
}

}  // namespace

TEST_CASE("a painted volume's .vdb holds a Vec3s colour grid in linear light, which OpenVDB reads and the loader takes back",
          "[openvdb][color]") {
  const Volume pig = paintedPig();
  REQUIRE(pig.paintedBricks() > 0);
  const std::string path = scratch("painted-pig.vdb");
  saveVdb(pig, path);

  openvdb::io::File file(path);
  file.open();
  auto color = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("color"));
  file.close();
  REQUIRE(color);
  CHECK(color->voxelSize()[0] == Approx(1.0));
  CHECK(color->background() == openvdb::Vec3s(srgbToLinear(221), srgbToLinear(181), srgbToLinear(155)));
  auto acc = color->getConstAccessor();
  std::size_t wrong = 0, active = 0, painted = 0;
  const Int3 d = pig.dims();
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        const Rgb8 c = pig.texel({x, y, z}).color();
        const openvdb::Vec3s want(srgbToLinear(c.r), srgbToLinear(c.g), srgbToLinear(c.b));
        wrong += acc.getValue(openvdb::Coord(x, y, z)) == want ? 0 : 1;
        active += acc.isValueOn(openvdb::Coord(x, y, z)) ? 1 : 0;
        painted += c == kClayColor ? 0 : 1;
      }
  INFO(painted << " voxels painted, " << active << " active colours");
  CHECK(wrong == 0);
  CHECK(active == painted);
  CHECK(painted > 10000);

  const Volume back = loadVdb(path, d);
  CHECK(texels(back) == texels(pig));
  CHECK(digest(back) == digest(pig));
  std::filesystem::remove(path);

  // Unpainted, no colour grid: the file is the level set alone, as before colour existed.
  const Volume plain = makeSolid(SolidKind::Pig, {72, 64, 56});
  saveVdb(plain, path);
  openvdb::io::File again(path);
  again.open();
  CHECK_FALSE(again.hasGrid("color"));
  again.close();
  CHECK(loadVdb(path, d).paintedBricks() == 0);
  std::filesystem::remove(path);
}

TEST_CASE("a .vdb upload takes its colour grid, after the float grid in a stream or anywhere with offsets", "[openvdb][color]") {
  openvdb::initialize();
  const Volume pig = paintedPig();
  std::stringstream stream(std::ios::in | std::ios::out | std::ios::binary);
  saveVdb(pig, stream);
  const std::string bytes = stream.str();
  const auto load = [&](const std::string& b) {
    std::istringstream in(b, std::ios::binary);
    return loadVdb(in, pig.dims());
  };
  const Volume back = load(bytes);
  CHECK(texels(back) == texels(pig));
  CHECK(digest(back) == digest(pig));

  // The same grids from OpenVDB's own writers: with offsets, the colour grid first or between
  // others; a stream with another grid between the two loads the surface without colours.
  std::istringstream in(bytes, std::ios::binary);
  openvdb::GridPtrVecPtr grids = openvdb::io::Stream(in, false).getGrids();
  REQUIRE(grids->size() == 2);
  const openvdb::GridBase::Ptr surface = (*grids)[0], color = (*grids)[1];
  auto velocity = openvdb::Vec3SGrid::create();
  velocity->setName("velocity");
  velocity->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1, 0, 0));
  CHECK(texels(load(fileBytes({color, velocity, surface}, "color-first.vdb"))) == texels(pig));
  CHECK(texels(load(fileBytes({surface, velocity, color}, "color-last.vdb"))) == texels(pig));
  const Volume apart = load(streamBytes({surface, velocity, color}));
  CHECK(apart.paintedBricks() == 0);
  CHECK(digest(apart) == digest(makeSolid(SolidKind::Pig, {72, 64, 56})));

  // A colour of NaN is refused with the place it was found; so is a prefix of the colour grid.
  auto bad = openvdb::gridPtrCast<openvdb::Vec3SGrid>(color->deepCopyGrid());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Int3 p = [&] {
    for (int z = 20;; ++z)
      if (std::fabs(pig.at(36, 32, z)) < pig.band()) return Int3{36, 32, z};
  }();
  bad->tree().setValue(openvdb::Coord(p.x, p.y, p.z), openvdb::Vec3s(nan, 0, 0));
  std::istringstream nanIn(streamBytes({surface, bad}), std::ios::binary);
  try {
    loadVdb(nanIn, pig.dims());
    FAIL("a NaN colour loaded");
  } catch (const EngineError& e) {
    CHECK_THAT(std::string(e.what()), Catch::Contains("the colour at (36, 32, " + std::to_string(p.z) + ") is not finite"));
  }
  std::istringstream cut(bytes.substr(0, bytes.size() - 10), std::ios::binary);
  CHECK_THROWS_AS(loadVdb(cut, pig.dims()), EngineError);
}
