// OpenVDB level-set files (conventions in vdb_io.hpp).
#include "engine/openvdb/vdb_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <istream>
#include <mutex>
#include <new>
#include <ostream>
#include <vector>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>
#include <openvdb/tools/SignedFloodFill.h>

#include "engine/brick.hpp"
#include "engine/errors.hpp"

namespace marzipan {

namespace {

void initialize() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

openvdb::FloatGrid::Ptr levelSetOf(const Volume& vol) {
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
  return grid;
}

std::string boxText(const openvdb::CoordBBox& b) {
  const auto c = [](const openvdb::Coord& p) {
    return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")";
  };
  return c(b.min()) + " to " + c(b.max());
}

// Copies the first float grid of `grids` into a volume of `dims`, after checking that its active
// voxels and tiles lie inside the domain (a grid of absurd extent is refused before any copy).
Volume volumeOf(const openvdb::GridPtrVecPtr& grids, Int3 dims, float band, const std::string& source) {
  openvdb::FloatGrid::Ptr grid;
  for (std::size_t i = 0; grids && i < grids->size() && !grid; ++i)
    grid = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[i]);
  if (!grid) throw EngineError(ErrorKind::Format, "file", source + " holds no float grid");
  const openvdb::CoordBBox active = grid->evalActiveVoxelBoundingBox();
  const openvdb::CoordBBox domain(openvdb::Coord(0, 0, 0), openvdb::Coord(dims.x - 1, dims.y - 1, dims.z - 1));
  if (!active.empty() && !domain.isInside(active))
    throw EngineError(ErrorKind::Format, "file",
                      source + ": the grid's active voxels span " + boxText(active) + ", outside the session's " +
                          boxText(domain));
  Volume vol(dims, band);
  auto acc = grid->getConstAccessor();
  // One slab of bricks at a time: the whole dense box of a 1024^3 domain would take 4 GiB.
  for (int z0 = 0; z0 < dims.z; z0 += kBrickSide) {
    const Box slab{{0, 0, z0}, {dims.x, dims.y, std::min(dims.z, z0 + kBrickSide)}};
    const Int3 size = slab.hi - slab.lo;
    std::vector<float> values(std::size_t(size.x) * size.y * size.z);
    for (int z = 0; z < size.z; ++z)
      for (int y = 0; y < size.y; ++y)
        for (int x = 0; x < size.x; ++x) {
          const float v = acc.getValue(openvdb::Coord(x, y, z0 + z));
          if (!std::isfinite(v))
            throw EngineError(ErrorKind::Format, "file",
                              source + ": the grid's value at (" + std::to_string(x) + ", " + std::to_string(y) +
                                  ", " + std::to_string(z0 + z) + ") is not a finite number");
          values[std::size_t(x) + std::size_t(size.x) * (y + std::size_t(size.y) * z)] = std::clamp(v, -band, band);
        }
    vol.scatter(slab, values.data(), slab);
  }
  return vol;
}

// Walks the part of a .vdb stream whose lengths OpenVDB trusts, up to the first grid's tree: the
// header, the file's metadata, the first grid's descriptor, compression, metadata and transform
// type. OpenVDB sizes a string or a metadata value from its declared 32-bit length and fills it
// before reading (up to 4 GiB from a few bytes), so each length must fit in the bytes that follow.
// Only the layouts of file versions 222 (OpenVDB 3) to this OpenVDB's own are accepted. Leaves
// the stream where it was.
class DeclaredLengths {
 public:
  explicit DeclaredLengths(std::istream& in) : in_(in), start_(in.tellg()) {
    in_.seekg(0, std::ios::end);
    const std::streamoff end = in_.tellg();
    in_.seekg(start_);
    if (start_ < 0 || end < start_) fail("a .vdb must come from a seekable stream");
    left_ = std::uint64_t(end - start_);
  }
  ~DeclaredLengths() {
    in_.clear();
    in_.seekg(start_);
  }

  void check() {
    if (u64() != std::uint64_t(openvdb::OPENVDB_MAGIC)) fail("not a .vdb file (no OpenVDB magic number)");
    const std::uint32_t version = u32();
    if (version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION || version > openvdb::OPENVDB_FILE_VERSION)
      fail("file format version " + std::to_string(version) + " is not one this server reads (222 to " +
           std::to_string(openvdb::OPENVDB_FILE_VERSION) + ")");
    skip(4 + 4 + 1 + 36);  // library major and minor, has-offsets flag, UUID as 36 characters
    metaMap();
    const std::int32_t grids = std::int32_t(u32());
    if (grids < 0 || std::uint64_t(grids) > left_ / 40) fail("declares " + std::to_string(grids) + " grids");
    if (grids == 0) return;
    string();  // unique name
    string();  // grid type
    string();  // instance parent
    skip(3 * 8 + 4);  // grid, block and end offsets; the grid's compression flags
    metaMap();
    string();  // the transform's map type
  }

 private:
  [[noreturn]] static void fail(const std::string& what) {
    throw EngineError(ErrorKind::Format, "file", "not a readable .vdb file: " + what);
  }
  void skip(std::uint64_t n) {
    if (n > left_) fail("it ends inside its header or metadata");
    in_.seekg(std::streamoff(n), std::ios::cur);
    left_ -= n;
  }
  std::uint64_t read(int bytes) {
    if (std::uint64_t(bytes) > left_) fail("it ends inside its header or metadata");
    unsigned char b[8] = {};
    in_.read(reinterpret_cast<char*>(b), bytes);
    left_ -= std::uint64_t(bytes);
    std::uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) v = v << 8 | b[i];
    return v;
  }
  std::uint32_t u32() { return std::uint32_t(read(4)); }
  std::uint64_t u64() { return read(8); }
  void string() {
    const std::uint32_t n = u32();
    if (n > left_) fail("a name declares " + std::to_string(n) + " bytes, more than the file holds");
    skip(n);
  }
  void metaMap() {
    const std::uint32_t count = u32();
    if (count > left_ / 12) fail("declares " + std::to_string(count) + " metadata entries");
    for (std::uint32_t i = 0; i < count; ++i) {
      string();  // name
      string();  // type name
      const std::uint32_t n = u32();
      if (n > left_) fail("a metadata value declares " + std::to_string(n) + " bytes, more than the file holds");
      skip(n);
    }
  }

  std::istream& in_;
  std::streamoff start_;
  std::uint64_t left_ = 0;
};

}  // namespace

void saveVdb(const Volume& vol, const std::string& path) {
  const openvdb::FloatGrid::Ptr grid = levelSetOf(vol);
  try {
    openvdb::io::File file(path);
    file.write({grid});
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::InvalidArgument, "path", std::string("cannot write ") + path + ": " + e.what());
  }
}

void saveVdb(const Volume& vol, std::ostream& out) {
  const openvdb::FloatGrid::Ptr grid = levelSetOf(vol);
  openvdb::io::Stream(out).write({grid});
}

Volume loadVdb(const std::string& path, Int3 dims, float band) {
  initialize();
  auto grids = std::make_shared<openvdb::GridPtrVec>();
  try {
    openvdb::io::File file(path);
    file.open();
    for (auto it = file.beginName(); it != file.endName() && grids->empty(); ++it) {
      auto grid = file.readGrid(it.gridName());
      if (openvdb::gridPtrCast<openvdb::FloatGrid>(grid)) grids->push_back(grid);
    }
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::Format, "file", std::string("cannot read ") + path + ": " + e.what());
  }
  return volumeOf(grids, dims, band, path);
}

Volume loadVdb(std::istream& in, Int3 dims, float band) {
  initialize();
  openvdb::GridPtrVecPtr grids;
  // A read past the end throws at once: OpenVDB's loops over declared counts (tiles, children)
  // would otherwise go on over a failed stream, allocating a node for each.
  DeclaredLengths(in).check();
  const std::ios::iostate before = in.exceptions();
  in.exceptions(std::ios::failbit | std::ios::badbit);
  try {
    // delayLoad = false: with delayed loading OpenVDB copies the stream into a temporary file.
    grids = openvdb::io::Stream(in, false).getGrids();
  } catch (const std::bad_alloc&) {
    // Sizes declared in the tree (node counts, compressed lengths) that no memory can hold.
    in.exceptions(before);
    throw EngineError(ErrorKind::Format, "file", "not a readable .vdb file: it declares more data than the server can hold");
  } catch (const std::exception& e) {
    in.exceptions(before);
    throw EngineError(ErrorKind::Format, "file", std::string("not a readable .vdb file: ") + e.what());
  }
  in.exceptions(before);
  return volumeOf(grids, dims, band, "the .vdb file");
}

}  // namespace marzipan
