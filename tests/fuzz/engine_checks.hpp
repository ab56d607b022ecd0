// Shared by the fuzz targets of engine decoders: what any EngineError, decoded mesh and loaded
// volume must look like, whatever bytes they came from.
//
// Conventions: as fuzz.hpp (a broken promise aborts). Sizes are kept small so that a target
// that goes on from decoding to importing still runs thousands of inputs a second.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>

#include "engine/errors.hpp"
#include "engine/mesh_io.hpp"
#include "engine/volume.hpp"
#include "fuzz.hpp"

namespace marzipan::fuzz {

// The domain meshes are imported into, and the largest mesh imported (bigger ones are only
// parsed: importing is linear in triangles times bricks, and parsing is what is under test).
inline constexpr Int3 kImportDims{16, 16, 16};
inline constexpr std::size_t kMaxImportTriangles = 256;

// A decoder refused the bytes: with ErrorKind::Format and a short message (engine messages
// may quote raw input, so they are not held to UTF-8; replies escape them).
inline void expectFormatError(const EngineError& e) {
  expect(e.kind() == ErrorKind::Format, "a decoder refuses bytes with ErrorKind::Format");
  expect(!e.field().empty(), "a decoder's error names what it decoded");
  const std::string message = e.what();
  expect(!message.empty() && message.size() < kMaxMessageBytes, "an engine error message stays short");
}

// Every stored brick holds finite values within +-band and is canonical: not uniform, and +band
// past the domain's edge (volume.hpp, canonicalBrick), so equal fields store equal bricks.
inline void expectSoundVolume(const Volume& vol) {
  const float band = vol.band();
  vol.forEachPresentBrick([&](Int3 b, const Brick& br) {
    for (const float v : br.v) expect(std::isfinite(v) && std::fabs(v) <= band, "stored values are within +-band");
    auto copy = std::make_shared<Brick>(br);
    const BrickRef ref = vol.canonicalBrick(b, copy);
    expect(ref.data != nullptr, "a stored brick is not uniform");
    expect(std::memcmp(ref.data->v, br.v, sizeof br.v) == 0, "a stored brick is +band past the domain's edge");
  });
}

// A mesh a parser returned is well formed; a small one is imported as it is and fitted into a
// small domain, where it must give a sound volume or a Format / InvalidArgument refusal.
inline void expectSoundMesh(const Mesh& m) {
  expect(m.positions.size() % 3 == 0 && m.indices.size() % 3 == 0, "positions and indices come in threes");
  expect(!m.indices.empty(), "a parsed mesh has triangles");
  expect(m.triangleCount() <= kMaxMeshTriangles, "a parsed mesh is within kMaxMeshTriangles");
  expect(m.normals.empty() || m.normals.size() == m.positions.size(), "normals are absent or one per vertex");
  for (const float c : m.positions) expect(std::isfinite(c), "coordinates are finite");
  for (const float c : m.normals) expect(std::isfinite(c), "normals are finite");
  for (const std::uint32_t i : m.indices) expect(i < m.vertexCount(), "indices are in range");
  if (m.triangleCount() > kMaxImportTriangles) return;
  const auto import = [](const Mesh& placed) {
    try {
      expectSoundVolume(importMesh(placed, kImportDims));
    } catch (const EngineError& e) {
      expectFormatError(e);
    }
  };
  import(m);
  try {
    import(fitMeshToDomain(m, kImportDims, 2));
  } catch (const EngineError& e) {
    expectFormatError(e);
  }
}

}  // namespace marzipan::fuzz
