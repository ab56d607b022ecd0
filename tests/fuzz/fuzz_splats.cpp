// Fuzz target: splat buffers (protocol/cpp/splats.hpp, decodeSplats). What decodes must hold
// unit normals and positions inside each brick's encodable range, and encode again to a
// buffer of the same size that decodes to the same points.
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
  try {
    bricks = decodeSplats(fuzz::bytesOf(data, size));
  } catch (const EngineError& e) {
    fuzz::expectFormatError(e);
    return 0;
  }
  for (const BrickSplats& b : bricks) {
    const float o[3] = {float(b.brick.x * kBrickSide), float(b.brick.y * kBrickSide), float(b.brick.z * kBrickSide)};
    expect(b.points.size() <= std::size_t(kBrickVoxels), "at most one point per voxel of a brick");
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
  expect(encodedSplatsSize(bricks) == size, "the decoded bricks encode to as many bytes");
  expect(decodeSplats(encodeSplats(bricks)) == bricks, "decoded points are already quantized: they re-encode exactly");
  return 0;
}
