// OpenVDB level-set files (conventions in vdb_io.hpp).
#include "engine/openvdb/vdb_io.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <vector>

#include <openvdb/openvdb.h>
#include <openvdb/tools/SignedFloodFill.h>

#include "engine/brick.hpp"
#include "engine/errors.hpp"

namespace marzipan {

namespace {

void initialize() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

}  // namespace

void saveVdb(const Volume& vol, const std::string& path) {
  initialize();
  const float w = vol.band();
  auto grid = openvdb::FloatGrid::create(w);
  grid->setName("surface");
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(1.0));
  auto acc = grid->getAccessor();
  const Int3 dims = vol.dims();
  vol.forEachPresentBrick([&](Int3 b, const Brick& brick) {
    const Int3 o = Bricks::origin(b);
    for (int k = 0; k < kBrickVoxels; ++k) {
      const Int3 p = o + Bricks::local(k);
      if (p.x >= dims.x || p.y >= dims.y || p.z >= dims.z) continue;
      if (std::fabs(brick.v[k]) < w) acc.setValue(openvdb::Coord(p.x, p.y, p.z), brick.v[k]);
    }
  });
  // Inactive values take the sign of the nearest active ones: -w inside, +w outside.
  openvdb::tools::signedFloodFill(grid->tree());
  try {
    openvdb::io::File file(path);
    file.write({grid});
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::InvalidArgument, "path", std::string("cannot write ") + path + ": " + e.what());
  }
}

Volume loadVdb(const std::string& path, Int3 dims, float band) {
  initialize();
  openvdb::FloatGrid::Ptr grid;
  try {
    openvdb::io::File file(path);
    file.open();
    for (auto it = file.beginName(); it != file.endName() && !grid; ++it)
      grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(it.gridName()));
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::Format, "file", std::string("cannot read ") + path + ": " + e.what());
  }
  if (!grid) throw EngineError(ErrorKind::Format, "file", path + " holds no float grid");
  Volume vol(dims, band);
  auto acc = grid->getConstAccessor();
  // One slab of bricks at a time: the whole dense box of a 1024^3 domain would take 4 GiB.
  for (int z0 = 0; z0 < dims.z; z0 += kBrickSide) {
    const Box slab{{0, 0, z0}, {dims.x, dims.y, std::min(dims.z, z0 + kBrickSide)}};
    const Int3 size = slab.hi - slab.lo;
    std::vector<float> values(std::size_t(size.x) * size.y * size.z);
    for (int z = 0; z < size.z; ++z)
      for (int y = 0; y < size.y; ++y)
        for (int x = 0; x < size.x; ++x)
          values[std::size_t(x) + std::size_t(size.x) * (y + std::size_t(size.y) * z)] =
              std::clamp(acc.getValue(openvdb::Coord(x, y, z0 + z)), -band, band);
    vol.scatter(slab, values.data(), slab);
  }
  return vol;
}

}  // namespace marzipan
