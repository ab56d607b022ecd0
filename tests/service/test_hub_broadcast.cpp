// HeldSplats (service/hub/broadcast.hpp): a delta lists the bricks whose encoded points differ
// from what the session's clients were sent, and the record starts afresh past its bound; the
// splat frames made from the buffers.
#include <catch2/catch.hpp>

#include <cstdint>
#include <stdexcept>
#include <vector>

#include "engine/solids.hpp"
#include "engine/splats.hpp"
#include "protocol/cpp/splats.hpp"
#include "service/hub/broadcast.hpp"

using namespace marzipan;
using namespace marzipan::service;

namespace {

// A brick of n points spread over its voxels, all with normal +z.
BrickSplats filled(Int3 brick, int n) {
  BrickSplats b{brick, {}};
  for (int i = 0; i < n; ++i)
    b.points.push_back({float(8 * brick.x + i % 8), float(8 * brick.y + i / 8 % 8), float(8 * brick.z + i / 64), 0, 0, 1});
  return b;
}

std::uint32_t brickCount(const std::vector<std::uint8_t>& buffer) {
  REQUIRE(buffer.size() >= kSplatHeaderBytes);
  return std::uint32_t(buffer[8] | buffer[9] << 8 | buffer[10] << 16 | buffer[11] << 24);
}

}  // namespace

TEST_CASE("held splats: a delta lists the bricks whose blocks changed, in the order given", "[hub][splats]") {
  const Volume v = makeSolid(SolidKind::Sphere, {64, 64, 64});
  std::vector<BrickSplats> fresh = extractAllSplats(v);
  REQUIRE(fresh.size() > 20);
  fresh.push_back({{7, 7, 7}, {}});  // a brick without points
  HeldSplats held;
  // Nothing recorded: every brick, exactly as encodeSplats writes them.
  CHECK(held.delta(fresh, v) == encodeSplats(fresh));
  CHECK(held.blocks.size() == fresh.size());
  // The same again: no brick.
  CHECK(held.delta(fresh, v) == encodeSplats({}));
  // Two bricks change (one loses a point, the empty one gains one), one changes back and forth.
  std::vector<BrickSplats> next = fresh;
  next[3].points.pop_back();
  next.back() = filled({7, 7, 7}, 1);
  CHECK(held.delta(next, v) == encodeSplats({next[3], next.back()}));
  // After room for a frame's header (as the broadcaster asks): the same buffer behind it.
  const std::vector<std::uint8_t> roomy = held.delta(fresh, v, 24);
  CHECK(std::vector<std::uint8_t>(roomy.begin() + 24, roomy.end()) == encodeSplats({fresh[3], fresh.back()}));
  // Floats that encode alike are the same block (a client could not tell them apart).
  next = fresh;
  const float code = decodeSplats(encodeSplats({fresh[5]}))[0].points[0].x;
  next[5].points[0].x = code + 1e-4f;  // within half a position step (3/8192 vu) of its code
  CHECK(next[5].points[0].x != fresh[5].points[0].x);
  CHECK(held.delta(next, v) == encodeSplats({}));
  next[5].points[0].x = code + 1e-3f;  // past it
  CHECK(held.delta(next, v) == encodeSplats({next[5]}));
}

TEST_CASE("held blocks: each brick's block found again, through growth and clearing", "[hub][splats]") {
  HeldBlocks blocks;
  CHECK(blocks.empty());
  // Bricks of a 40 x 40 x 3 domain, the keys a delta uses: the array grows many times over.
  std::vector<std::uint64_t> keys;
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 40; ++y)
      for (int x = 0; x < 40; ++x) keys.push_back(splatBrickKey({x, y, z}));
  std::vector<const std::uint8_t*> data;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto [block, added] = blocks.findOrAdd(keys[i]);
    REQUIRE(added);
    REQUIRE(block->empty());
    *block = {std::uint8_t(i), std::uint8_t(i >> 8), std::uint8_t(i >> 16)};
    data.push_back(block->data());
  }
  CHECK(blocks.size() == keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto [block, added] = blocks.findOrAdd(keys[i]);
    CHECK_FALSE(added);
    CHECK(*block == std::vector<std::uint8_t>{std::uint8_t(i), std::uint8_t(i >> 8), std::uint8_t(i >> 16)});
    CHECK(block->data() == data[i]);  // the bytes stayed where they were as the array grew
  }
  CHECK(blocks.size() == keys.size());
  std::size_t visited = 0;
  blocks.forEach([&](std::uint64_t key, const std::vector<std::uint8_t>& block) {
    const std::size_t i = std::size_t(block[0]) | std::size_t(block[1]) << 8 | std::size_t(block[2]) << 16;
    REQUIRE(i < keys.size());
    CHECK(keys[i] == key);
    ++visited;
  });
  CHECK(visited == keys.size());
  blocks.clear();
  CHECK(blocks.empty());
  const auto [block, added] = blocks.findOrAdd(keys[7]);
  CHECK(added);
  CHECK(block->empty());
  CHECK(blocks.size() == 1);
}

TEST_CASE("held splats: past half the volume's memory the record starts afresh", "[hub][splats]") {
  const Volume small = makeSolid(SolidKind::Sphere, {16, 16, 16});
  REQUIRE(small.memoryBytes() / 2 < HeldSplats::kCheckBytes);
  // Blocks of 512 points (4104 bytes): past kCheckBytes with enough of them.
  const auto bricks = [](int count) {
    std::vector<BrickSplats> out;
    for (int i = 0; i < count; ++i) out.push_back(filled({i % 64, i / 64, 0}, 512));
    return out;
  };
  const std::size_t block = kSplatBrickHeaderBytes + 512 * kSplatPointBytes;
  const int under = int(HeldSplats::kCheckBytes / (block + HeldSplats::kEntryBytes)) - 1;
  HeldSplats held;
  CHECK(brickCount(held.delta(bricks(under), small)) == std::uint32_t(under));
  CHECK(held.bytes == std::size_t(under) * (block + HeldSplats::kEntryBytes));
  CHECK(brickCount(held.delta(bricks(under), small)) == 0);
  // Two more bricks cross the bound: they are sent, then the record is empty, so everything
  // is sent again the next time (once).
  CHECK(brickCount(held.delta(bricks(under + 2), small)) == 2);
  CHECK(held.blocks.empty());
  CHECK(held.bytes == 0);
  CHECK(brickCount(held.delta(bricks(under), small)) == std::uint32_t(under));
  CHECK(brickCount(held.delta(bricks(under), small)) == 0);
}

TEST_CASE("held splats: the record counts the memory its blocks keep, not only what they hold", "[hub][splats]") {
  // Bricks the surface passed through and left: a full block (4104 bytes) replaced by an empty
  // one must not keep its old storage uncounted (15 such rounds kept 12 MB under a 0.2 MB count).
  const Volume small = makeSolid(SolidKind::Sphere, {16, 16, 16});
  std::vector<BrickSplats> full, empty;
  for (int i = 0; i < 100; ++i) {
    full.push_back(filled({i % 64, i / 64, 0}, 512));
    empty.push_back({{i % 64, i / 64, 0}, {}});
  }
  HeldSplats held;
  for (int round = 0; round < 3; ++round) {
    held.delta(full, small);
    held.delta(empty, small);
    std::size_t kept = 0;
    held.blocks.forEach([&](std::uint64_t, const std::vector<std::uint8_t>& block) {
      kept += block.capacity() + HeldSplats::kEntryBytes;
    });
    CHECK(held.bytes == kept);
    CHECK(kept < 100 * (kSplatBrickHeaderBytes + 16 + HeldSplats::kEntryBytes));
  }
}

TEST_CASE("a frame made in place of its buffer is the frame made around its payload, not a copy", "[hub][splats]") {
  const Volume v = makeSolid(SolidKind::Sphere, {32, 32, 32});
  const std::vector<BrickSplats> fresh = extractAllSplats(v);
  HeldSplats held;
  Bytes roomy = held.delta(fresh, v, protocol::kFrameHeaderBytes);
  const std::uint8_t* const payloadAt = roomy.data();
  const Bytes payload(roomy.begin() + std::ptrdiff_t(protocol::kFrameHeaderBytes), roomy.end());
  REQUIRE(payload == encodeSplats(fresh));
  const SharedBytes frame = makeFrameInPlace(protocol::FrameKind::SplatsDelta, 9, 123456789012ull, std::move(roomy));
  CHECK(*frame == *makeFrame(protocol::FrameKind::SplatsDelta, 9, 123456789012ull, payload));
  CHECK(frame->data() == payloadAt);
  CHECK_THROWS_AS(makeFrameInPlace(protocol::FrameKind::SplatsDelta, 0, 1, Bytes(protocol::kFrameHeaderBytes - 1)),
                  std::invalid_argument);
}

TEST_CASE("a splat frame for a client of version 1: the same frame, its colours dropped", "[hub][splats][paint]") {
  std::vector<BrickSplats> bricks = {filled({1, 2, 3}, 5), filled({4, 0, 2}, 3), {{7, 7, 7}, {}}};
  bricks[0].texels.assign(5, SplatTexel{200, 20, 10, 255});
  const std::vector<std::uint8_t> v2 = encodeSplats(bricks, 2);
  const SharedBytes frame = makeFrame(protocol::FrameKind::SplatsDelta, 17, 42, v2);
  const SharedBytes plain = plainFrame(*frame);
  const protocol::DecodedFrame f = *protocol::decodeFrameHeader(*plain).frame;
  CHECK(f.header.kind == protocol::FrameKind::SplatsDelta);
  CHECK(f.header.requestId == 17);
  CHECK(f.header.revision == 42);
  const std::vector<std::uint8_t> payload(f.payload.begin(), f.payload.end());
  CHECK(payload == encodeSplats(bricks, 1));
  CHECK(payload.size() == v2.size() - 5 * 4);
  // A frame of version 1 already stays byte for byte.
  CHECK(*plainFrame(*plain) == *plain);
}
