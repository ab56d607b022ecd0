// The native volume file: round trips keep digest and revision; truncated, corrupted and
// hand-built invalid files are refused with ErrorKind::Format. Layout as in volume_file.hpp.
#include <bit>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "engine/volume.hpp"
#include "engine/volume_file.hpp"
#include "support.hpp"

using namespace marzipan;

namespace {

void put32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}

// Recomputes the trailing CRC-32, so that a hand-edited file fails on its content only.
std::vector<std::uint8_t> resealed(std::vector<std::uint8_t> b) {
  put32(b, b.size() - 4, crc32Ieee({b.data(), b.size() - 4}));
  return b;
}

// The message of the Format error loading `bytes` raises, or "" when it loads.
std::string formatErrorOf(std::span<const std::uint8_t> bytes) {
  try {
    loadVolume(bytes);
  } catch (const EngineError& e) {
    return e.kind() == ErrorKind::Format ? std::string(e.what()) : "wrong kind: " + std::string(e.what());
  }
  return "";
}

bool contains(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("CRC-32 matches the standard check value", "[file]") {
  const std::string check = "123456789";
  CHECK(crc32Ieee({reinterpret_cast<const std::uint8_t*>(check.data()), check.size()}) == 0xCBF43926u);
  CHECK(crc32Ieee({}) == 0u);
}

TEST_CASE("saving and loading keeps digest, revision and every brick", "[file]") {
  for (const SolidKind kind : {SolidKind::Sphere, SolidKind::Pig, SolidKind::Torus, SolidKind::Box}) {
    for (const Int3 dims : {Int3{64, 64, 64}, Int3{70, 61, 53}}) {
      Volume v = makeSolid(kind, dims);
      v.setRevision(1234567890123ull);
      const auto bytes = saveVolume(v);
      INFO(solidKindName(kind) << " " << dims.x << "x" << dims.y << "x" << dims.z);
      CHECK(bytes.size() == savedVolumeSize(v));
      const Volume back = loadVolume(bytes);
      CHECK(digest(back) == digest(v));
      CHECK(back.revision() == v.revision());
      CHECK(back.dims() == v.dims());
      CHECK(back.band() == v.band());
      CHECK(back.presentBricks() == v.presentBricks());
      CHECK(saveVolume(back) == bytes);
    }
  }
}

TEST_CASE("edited, empty, full and wide-band volumes round-trip", "[file]") {
  Volume edited = makeSolid(SolidKind::Sphere, {48, 48, 48});
  addBlob(edited, {{40.0, 24.0, 24.0}, 6.0, 1.0});
  removeBlob(edited, {{24.0, 8.0, 24.0}, 5.0, 1.0});
  edited.setRevision(2);
  Volume empty({24, 16, 8});
  Volume full({40, 40, 40});
  full.fill(true);
  full.setRevision(7);
  Volume wide = makeSolid(SolidKind::Dumbbell, {64, 40, 40}, 6.0f);
  for (const Volume* v : {&edited, &empty, &full, &wide}) {
    const Volume back = loadVolume(saveVolume(*v));
    CHECK(digest(back) == digest(*v));
    CHECK(back.revision() == v->revision());
    CHECK(back.at(20, 20, 20) == v->at(20, 20, 20));
  }
  CHECK(saveVolume(empty).size() == 48 + 4);
  CHECK(saveVolume(full).size() == 48 + 125 * 8 + 4);
}

TEST_CASE("every truncated prefix and every single-byte corruption is refused", "[file][errors]") {
  Volume v = makeSolid(SolidKind::Sphere, {16, 16, 16});
  v.setRevision(3);
  const auto bytes = saveVolume(v);
  REQUIRE(bytes.size() > 4 * 2056);

  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string e = formatErrorOf(std::span<const std::uint8_t>(bytes.data(), n));
    REQUIRE(!e.empty());
    REQUIRE(!contains(e, "wrong kind"));
  }
  auto longer = bytes;
  longer.push_back(0);
  CHECK(contains(formatErrorOf(longer), "trailing"));

  std::size_t checksumErrors = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    for (const std::uint8_t flip : {std::uint8_t(0x01), std::uint8_t(0xFF)}) {
      auto bad = bytes;
      bad[i] ^= flip;
      const std::string e = formatErrorOf(bad);
      REQUIRE(!e.empty());
      REQUIRE(!contains(e, "wrong kind"));
      checksumErrors += contains(e, "checksum");
    }
  }
  // Past the header the checksum is the first check to notice a change.
  CHECK(checksumErrors >= 2 * (bytes.size() - 48));
}

TEST_CASE("hand-built files with bad contents are refused with a clear reason", "[file][errors]") {
  const Volume v = makeSolid(SolidKind::Sphere, {16, 16, 24});
  const auto good = saveVolume(v);
  REQUIRE(formatErrorOf(good).empty());
  const std::size_t firstBrick = 48;
  std::uint32_t present = 0;
  std::memcpy(&present, good.data() + 36, 4);
  REQUIRE(present >= 2);

  auto edit = [&](auto change) {
    auto b = good;
    change(b);
    return formatErrorOf(resealed(b));
  };
  CHECK(contains(edit([](auto& b) { b[0] = 'X'; }), "magic"));
  CHECK(contains(edit([](auto& b) { put32(b, 4, 3); }), "version 3"));
  CHECK(contains(edit([](auto& b) { put32(b, 4, 0); }), "version 0"));
  // A version-1 file relabelled 2 lacks the base colour.
  CHECK(contains(edit([](auto& b) { put32(b, 4, 2); }), "size mismatch"));
  CHECK(contains(edit([](auto& b) { put32(b, 8, 4); }), "dimension"));
  CHECK(contains(edit([](auto& b) { put32(b, 8, 2048); }), "dimension"));
  CHECK(contains(edit([](auto& b) { put32(b, 20, std::bit_cast<std::uint32_t>(10.0f)); }), "band"));
  CHECK(contains(edit([](auto& b) { put32(b, 20, std::bit_cast<std::uint32_t>(std::nanf(""))); }), "band"));
  CHECK(contains(edit([](auto& b) { put32(b, 32, 16); }), "brick side"));
  CHECK(contains(edit([](auto& b) { put32(b, 44, 1); }), "reserved"));
  CHECK(contains(edit([](auto& b) { put32(b, 36, 0xFFFFFFFFu); }), "exceed"));
  CHECK(contains(edit([&](auto& b) { put32(b, 36, present - 1); }), "size mismatch"));
  // Dims that no longer hold the bricks: z shrinks from 24 to 8 voxels, one brick layer.
  {
    auto b = good;
    put32(b, 16, 8);
    const std::string e = formatErrorOf(resealed(b));
    CHECK((contains(e, "outside the brick grid") || contains(e, "exceed")));
  }
  // The second stored brick gets the first one's address.
  CHECK(contains(edit([&](auto& b) { std::memcpy(b.data() + firstBrick + 2056, b.data() + firstBrick, 6); }),
                 "listed twice"));
  CHECK(contains(edit([&](auto& b) { b[firstBrick + 6] = 1; }), "reserved"));
  CHECK(contains(
      edit([&](auto& b) { put32(b, firstBrick + 8 + 4 * 100, std::bit_cast<std::uint32_t>(std::nanf(""))); }), "NaN"));
  CHECK(contains(edit([&](auto& b) { put32(b, firstBrick + 8, std::bit_cast<std::uint32_t>(3.5f)); }), "band"));
  CHECK(contains(edit([&](auto& b) {
                   put32(b, firstBrick + 8, std::bit_cast<std::uint32_t>(std::numeric_limits<float>::infinity()));
                 }),
                 "band"));
}

TEST_CASE("random corruptions behind a valid checksum load or are refused, never crash", "[file][errors]") {
  const Volume v = makeSolid(SolidKind::Torus, {24, 16, 24});
  const auto good = saveVolume(v);
  std::mt19937 rng(11);
  int loaded = 0, refused = 0;
  for (int t = 0; t < 1500; ++t) {
    auto bad = good;
    // Mostly the header and brick addresses, where the interesting checks are.
    const int flips = 1 + int(rng() % 3);
    for (int f = 0; f < flips; ++f) {
      const std::size_t at = (rng() % 2) ? rng() % 56 : rng() % (bad.size() - 4);
      bad[at] ^= std::uint8_t(1 + rng() % 255);
    }
    const std::string e = formatErrorOf(resealed(bad));
    REQUIRE(!contains(e, "wrong kind"));
    (e.empty() ? loaded : refused) += 1;
  }
  CHECK(refused > 0);
  CHECK(loaded + refused == 1500);
}

TEST_CASE("a brick listed both as stored and as inside is refused", "[file][errors]") {
  Volume v({16, 16, 16});
  const Box half{{0, 0, 0}, {16, 16, 8}};
  std::vector<float> vals(std::size_t(half.voxels()), -v.band());
  v.scatter(half, vals.data(), half);  // four inside bricks, z = 0
  const Box one{{0, 0, 8}, {8, 8, 16}};
  std::vector<float> mixed(std::size_t(one.voxels()));
  for (std::size_t i = 0; i < mixed.size(); ++i) mixed[i] = float(int(i % 5) - 2);
  v.scatter(one, mixed.data(), one);  // brick (0, 0, 1) stored
  auto bytes = saveVolume(v);
  REQUIRE(bytes.size() == 48 + 2056 + 4 * 8 + 4);
  // Point the first inside brick at the stored brick's address.
  std::memcpy(bytes.data() + 48 + 2056, bytes.data() + 48, 6);
  CHECK(contains(formatErrorOf(resealed(bytes)), "both"));
}

TEST_CASE("volume files on disk", "[file]") {
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("marzipan-file-test-" + std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "pig.mzv").string();
  Volume v = makeSolid(SolidKind::Pig, {48, 40, 40});
  v.setRevision(9);
  saveVolumeFile(v, path);
  CHECK(!std::filesystem::exists(path + ".tmp"));
  CHECK(std::filesystem::file_size(path) == savedVolumeSize(v));
  const Volume back = loadVolumeFile(path);
  CHECK(digest(back) == digest(v));
  CHECK(back.revision() == 9);
  try {
    loadVolumeFile((dir / "missing.mzv").string());
    FAIL("no error");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::InvalidArgument);
    CHECK(e.field() == "path");
  }
  CHECK_THROWS_AS(saveVolumeFile(v, (dir / "no-such-dir" / "x.mzv").string()), EngineError);
  std::filesystem::remove_all(dir);
}

TEST_CASE("size of the file of a radius-100 sphere", "[file]") {
  const Volume v = makeSphere({256, 256, 256}, {127.6, 128.2, 127.9}, 100);
  const auto bytes = saveVolume(v);
  std::size_t inside = 0;
  v.forEachInsideBrick([&](Int3) { ++inside; });
  CHECK(bytes.size() == 48 + 2056 * v.presentBricks() + 8 * inside + 4);
  // Only stored bricks cost: the file is about the size of the volume in memory.
  CHECK(double(bytes.size()) < 1.1 * double(v.memoryBytes()));
  INFO("radius-100 sphere in 256^3: " << bytes.size() << " bytes (" << v.presentBricks() << " stored, " << inside
                                      << " inside bricks; " << v.memoryBytes() << " bytes in memory)");
  CHECK(bytes.size() < std::size_t(9e6));  // 8.37 MB measured
  CHECK(digest(loadVolume(bytes)) == digest(v));
}

TEST_CASE("voxels past the domain's far edge must be +band in a loaded file", "[file][errors]") {
  // 20 voxels along x: bricks at x = 2 hold voxels 16..19 in the domain and 20..23 past it.
  const Volume v = makeSolid(SolidKind::Sphere, {20, 16, 16});
  auto bytes = saveVolume(v);
  std::uint32_t present = 0;
  std::memcpy(&present, bytes.data() + 36, 4);
  std::size_t edgeBrick = 0;
  for (std::uint32_t i = 0; i < present && !edgeBrick; ++i) {
    const std::size_t at = 48 + 2056 * std::size_t(i);
    if (bytes[at] == 2 && bytes[at + 1] == 0) edgeBrick = at;
  }
  REQUIRE(edgeBrick != 0);
  // Local voxel (7, 3, 3) is x = 23, past the edge; inside the sphere's band it would pass.
  put32(bytes, edgeBrick + 8 + 4 * (7 + 8 * (3 + 8 * 3)), std::bit_cast<std::uint32_t>(-1.0f));
  CHECK(contains(formatErrorOf(resealed(bytes)), "past the domain"));
}

TEST_CASE("a stored brick that is uniformly inside or outside is refused", "[file][errors]") {
  // Volume stores such a brick as a uniform slot (canonicalBrick); a file that stores it anyway
  // would load into a volume whose digest differs from that of the same field built any other way.
  const Volume v = makeSolid(SolidKind::Sphere, {20, 16, 16});
  const auto good = saveVolume(v);
  std::uint32_t present = 0;
  std::memcpy(&present, good.data() + 36, 4);
  const float band = v.band();
  for (const float side : {band, -band}) {
    for (std::uint32_t i = 0; i < present; ++i) {
      const std::size_t at = 48 + 2056 * std::size_t(i);
      auto bytes = good;
      // Every voxel of the domain takes `side`; voxels past the far x edge (x >= 20) stay +band.
      for (int k = 0; k < 512; ++k) {
        const bool past = int(bytes[at]) * 8 + (k & 7) >= 20;
        put32(bytes, at + 8 + 4 * std::size_t(k), std::bit_cast<std::uint32_t>(past ? band : side));
      }
      INFO("stored brick " << i << ", value " << side);
      CHECK(contains(formatErrorOf(resealed(bytes)), "uniform"));
    }
  }
}

// --- version 2: the channels ---------------------------------------------------------------

namespace {

// A sphere with some bricks painted (colour varying per voxel, a weight in some) and others not.
Volume paintedSphere() {
  Volume v = makeSphere({40, 40, 48}, {20, 20, 24}, 13);
  test::paintBricks(v, [](Int3 b, int i) {
    if ((b.x + b.y + b.z) % 3 == 0) return texelOf(kClayColor);
    return Texel{std::uint8_t(i), std::uint8_t(7 * b.x), std::uint8_t(200 - b.z), std::uint8_t(b.y % 2 ? i / 2 : 0)};
  });
  return v;
}

}  // namespace

TEST_CASE("an unpainted volume of the clay colour is written as version 1, byte for byte as before", "[file][channels]") {
  const Volume v = makeSolid(SolidKind::Sphere, {32, 32, 32});
  const auto bytes = saveVolume(v);
  CHECK(bytes[4] == 1);
  std::size_t inside = 0;
  v.forEachInsideBrick([&](Int3) { ++inside; });
  CHECK(bytes.size() == 48 + 2056 * v.presentBricks() + 8 * inside + 4);
  // The bytes of version 1 (the layout before channels): header bytes 44..48 are 0.
  CHECK(bytes[44] == 0);
  CHECK(bytes[45] == 0);
  // Pinned: the size and checksum of this file as the code before channels wrote it (120ebd0).
  CHECK(bytes.size() == 115188);
  CHECK(crc32Ieee({bytes.data(), bytes.size() - 4}) == 0xba4cea68u);
  CHECK(digest(loadVolume(bytes)) == digest(v));
}

TEST_CASE("a painted volume round-trips through version 2 with every texel and its base colour", "[file][channels]") {
  Volume v = paintedSphere();
  v.setRevision(77);
  REQUIRE(v.paintedBricks() > 10);
  REQUIRE(v.paintedBricks() < v.presentBricks());
  const auto bytes = saveVolume(v);
  CHECK(bytes[4] == 2);
  CHECK(bytes.size() == savedVolumeSize(v));
  std::size_t inside = 0;
  v.forEachInsideBrick([&](Int3) { ++inside; });
  CHECK(bytes.size() == 48 + 2056 * v.presentBricks() + 8 * inside + 4 + 2056 * v.paintedBricks() + 4);
  const Volume back = loadVolume(bytes);
  CHECK(digest(back) == digest(v));
  CHECK(back.revision() == 77);
  CHECK(back.paintedBricks() == v.paintedBricks());
  std::size_t differ = 0;
  v.forEachPaintedBrick([&](Int3 b, const BrickPaint& bp) {
    const BrickPaint* other = back.brickPaint(b);
    differ += !other || !std::equal(std::begin(bp.t), std::end(bp.t), std::begin(other->t)) || other->masked != bp.masked;
  });
  CHECK(differ == 0);
  CHECK(saveVolume(back) == bytes);

  // Only a base colour: version 2 with no painted brick.
  Volume blue = makeSolid(SolidKind::Sphere, {16, 16, 16});
  blue.setBaseColor({1, 2, 250});
  const auto blueBytes = saveVolume(blue);
  CHECK(blueBytes[4] == 2);
  CHECK(loadVolume(blueBytes).baseColor() == Rgb8{1, 2, 250});
  CHECK(digest(loadVolume(blueBytes)) == digest(blue));
}

TEST_CASE("version 2: every truncated prefix and every single-byte corruption is refused", "[file][channels][errors]") {
  Volume v = makeSolid(SolidKind::Sphere, {16, 16, 16});
  test::paintBricks(v, [](Int3 b, int i) { return Texel{std::uint8_t(i), std::uint8_t(b.x), 3, std::uint8_t(i % 3)}; });
  const auto bytes = saveVolume(v);
  REQUIRE(bytes[4] == 2);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string e = formatErrorOf(std::span<const std::uint8_t>(bytes.data(), n));
    REQUIRE(!e.empty());
    REQUIRE(!contains(e, "wrong kind"));
  }
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    auto bad = bytes;
    bad[i] ^= 0x01;
    const std::string e = formatErrorOf(bad);
    REQUIRE(!e.empty());
    REQUIRE(!contains(e, "wrong kind"));
  }
}

TEST_CASE("version 2: painted bricks that are not stored, out of order or plain are refused", "[file][channels][errors]") {
  const Volume v = paintedSphere();
  const auto good = saveVolume(v);
  REQUIRE(formatErrorOf(good).empty());
  std::size_t inside = 0;
  v.forEachInsideBrick([&](Int3) { ++inside; });
  const std::size_t base = 48 + 2056 * v.presentBricks() + 8 * inside;
  const std::size_t firstPainted = base + 4;
  auto edit = [&](auto change) {
    auto b = good;
    change(b);
    return formatErrorOf(resealed(b));
  };
  CHECK(contains(edit([&](auto& b) { b[base + 3] = 1; }), "reserved byte of the base colour"));
  // An inside brick's address (never stored) for the first painted brick.
  CHECK(contains(edit([&](auto& b) {
                   std::memcpy(b.data() + firstPainted, b.data() + 48 + 2056 * v.presentBricks(), 6);
                 }),
                 "not a stored brick"));
  CHECK(contains(edit([&](auto& b) { std::memcpy(b.data() + firstPainted + 2056, b.data() + firstPainted, 6); }),
                 "listed twice"));
  CHECK(contains(edit([&](auto& b) {
                   for (int k = 0; k < kBrickVoxels; ++k) {
                     b[firstPainted + 8 + 4 * k] = kClayColor.r, b[firstPainted + 9 + 4 * k] = kClayColor.g;
                     b[firstPainted + 10 + 4 * k] = kClayColor.b, b[firstPainted + 11 + 4 * k] = 0;
                   }
                 }),
                 "only the base colour"));
  CHECK(contains(edit([&](auto& b) { put32(b, 44, std::uint32_t(v.presentBricks() + 1)); }), "exceed"));
  CHECK(contains(edit([&](auto& b) { put32(b, 44, std::uint32_t(v.paintedBricks() - 1)); }), "size mismatch"));
}
