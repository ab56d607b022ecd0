// Fuzz target: splat buffers of both versions (protocol/cpp/splats.hpp, decodeSplats). What
// decodes must hold unit normals and positions inside each brick's encodable range, texels none
// or one per point (none in version 1), and encode again in its version to a buffer of the same
// size that decodes to the same points; as version 1 it loses only the texels.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "protocol/cpp/splats.hpp"
#include "engine_checks.hpp"

using namespace marzipan;
using marzipan::fuzz::expect;

namespace {
constexpr int kMaxBricks = kMaxDomainSide / kBrickSide;
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<BrickSplats> bricks;
  std::uint16_t version = 0;
  try {
    bricks = decodeSplats(fuzz::bytesOf(data, size), &version);
  } catch (const EngineError& e) {
    fuzz::expectFormatError(e);
    return 0;
  }
  for (const BrickSplats& b : bricks) {
    const float o[3] = {float(b.brick.x * kBrickSide), float(b.brick.y * kBrickSide), float(b.brick.z * kBrickSide)};
    expect(b.points.size() <= std::size_t(kBrickVoxels), "at most one point per voxel of a brick");
    expect(b.texels.empty() || (version == 2 && b.texels.size() == b.points.size()),
           "texels are none or one per point, and only in version 2");
    // Brick coordinates go to 65535, far past the largest domain (128 bricks), where a float
    // is too coarse to keep the top of [o - 2, o + 10) open; there the interval closes.
    const bool inDomainRange[3] = {b.brick.x < kMaxBricks, b.brick.y < kMaxBricks, b.brick.z < kMaxBricks};
    for (const Splat& s : b.points) {
      const float q[3] = {s.x, s.y, s.z};
      for (int a = 0; a < 3; ++a)
        expect(q[a] >= o[a] - 2 && (inDomainRange[a] ? q[a] < o[a] + 10 : q[a] <= o[a] + 10),
               "a point lies in [o - 2, o + 10)");
      const float n2 = s.nx * s.nx + s.ny * s.ny + s.nz * s.nz;
      expect(std::fabs(n2 - 1) < 1e-5f, "a normal is unit length");
    }
  }
  expect(encodedSplatsSize(bricks, version) == size, "the decoded bricks encode to as many bytes");
  expect(decodeSplats(encodeSplats(bricks, version)) == bricks,
         "decoded points are already quantized: they re-encode exactly");
  std::vector<BrickSplats> plain = decodeSplats(splatsAsVersion1(fuzz::bytesOf(data, size)));
  for (BrickSplats& b : bricks) b.texels.clear();
  expect(plain == bricks, "as version 1 the buffer keeps its points and loses its texels");
  return 0;
}
