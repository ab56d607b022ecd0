// OpenVDB level-set files (conventions in vdb_io.hpp).
#include "engine/openvdb/vdb_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <istream>
#include <iterator>
#include <mutex>
#include <new>
#include <ostream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>
#include <openvdb/tools/SignedFloodFill.h>

#include "engine/brick.hpp"
#include "engine/color_space.hpp"
#include "engine/errors.hpp"
#include "engine/marching_cubes.hpp"  // carriesColor

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

openvdb::Vec3s linearOf(Rgb8 c) { return {srgbToLinear(c.r), srgbToLinear(c.g), srgbToLinear(c.b)}; }

// The colour grid: background the base colour, active where a voxel of a painted brick holds
// another colour, in linear light.
openvdb::Vec3SGrid::Ptr colorGridOf(const Volume& vol) {
  const Rgb8 base = vol.baseColor();
  auto grid = openvdb::Vec3SGrid::create(linearOf(base));
  grid->setName(kColorGridName);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(1.0));
  auto acc = grid->getAccessor();
  const Int3 dims = vol.dims();
  vol.forEachPaintedBrick([&](Int3 b, const BrickPaint& paint) {
    const Int3 o = Bricks::origin(b);
    for (int k = 0; k < kBrickVoxels; ++k) {
      const Int3 p = o + Bricks::local(k);
      if (p.x >= dims.x || p.y >= dims.y || p.z >= dims.z || paint.t[k].color() == base) continue;
      acc.setValue(openvdb::Coord(p.x, p.y, p.z), linearOf(paint.t[k].color()));
    }
  });
  return grid;
}

// The grids a volume is written as: its level set, and its colour when it carries colour.
openvdb::GridPtrVec gridsOf(const Volume& vol) {
  openvdb::GridPtrVec grids{levelSetOf(vol)};
  if (carriesColor(vol)) grids.push_back(colorGridOf(vol));
  return grids;
}

// Gives every stored brick of vol the colours of `grid` at its voxels (weight 0), the base colour
// past the domain's edge.
void takeColors(Volume& vol, const openvdb::Vec3SGrid& grid, const std::string& source) {
  auto acc = grid.getConstAccessor();
  const Int3 dims = vol.dims();
  std::vector<BrickChange> changes;
  vol.forEachPresentBrick([&](Int3 b, const Brick&) {
    auto paint = std::make_shared<BrickPaint>();
    const Int3 o = Bricks::origin(b);
    for (int k = 0; k < kBrickVoxels; ++k) {
      const Int3 p = o + Bricks::local(k);
      if (p.x >= dims.x || p.y >= dims.y || p.z >= dims.z) {
        paint->t[k] = texelOf(vol.baseColor());
        continue;
      }
      const openvdb::Vec3s c = acc.getValue(openvdb::Coord(p.x, p.y, p.z));
      if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2]))
        throw EngineError(ErrorKind::Format, "file",
                          source + ": the colour at (" + std::to_string(p.x) + ", " + std::to_string(p.y) + ", " +
                              std::to_string(p.z) + ") is not finite");
      paint->t[k] = {linearToSrgb(c[0]), linearToSrgb(c[1]), linearToSrgb(c[2]), 0};
    }
    BrickRef now = vol.brick(b);
    BrickRef old = now;
    now.paint = vol.canonicalPaint(std::move(paint));
    if (!(now == old)) changes.push_back({b, std::move(old), std::move(now)});
  });
  vol.publish(changes, true);
}

std::string boxText(const openvdb::CoordBBox& b) {
  const auto c = [](const openvdb::Coord& p) {
    return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")";
  };
  return c(b.min()) + " to " + c(b.max());
}

// Copies the first float grid of `grids` into a volume of `dims`, after checking that its active
// voxels and tiles lie inside the domain (a grid of absurd extent is refused before any copy),
// and stops once the volume's bricks pass maxBytes: the active voxels say nothing of the values
// between them, and a background inside the band makes every brick data.
Volume volumeOf(const openvdb::GridPtrVecPtr& grids, Int3 dims, float band, const std::string& source,
                std::size_t maxBytes) {
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
    if (vol.memoryBytes() > maxBytes)
      throw EngineError(ErrorKind::TooLarge, "file",
                        source + ": its volume takes more than " + std::to_string(maxBytes) + " bytes of bricks (" +
                            std::to_string(vol.memoryBytes()) + " by z = " + std::to_string(slab.hi.z) + " of " +
                            std::to_string(dims.z) + ")");
  }
  return vol;
}

// What of a client's .vdb upload OpenVDB is given: the header and the file's metadata, the grid
// count rewritten to 1, and the one grid that will be read (its descriptor, metadata, transform
// and tree). OpenVDB sizes a string or a metadata value from its declared 32-bit length and fills
// it before reading (up to 4 GiB from a few bytes), and reads every grid a file lists, so every
// length it would trust before that grid's tree is checked against the bytes that follow, and the
// grids it would not need are never shown to it. A file written with grid offsets (io::File, as
// VFX tools write) is walked grid by grid to its first float grid; one written without them (a
// stream, as volume.save writes) can only be read from its first grid, which must be the float
// one. Only the layouts of file versions 222 (OpenVDB 3) to this OpenVDB's own are accepted.
// The colour grid (vdb_io.hpp) is cut the same way, once the float grid has been read: with
// offsets, found by walking the descriptors; without, it must be the grid right after the float
// grid, where OpenVDB's reading of that grid stopped.
class GridCutter {
 public:
  explicit GridCutter(std::string_view file) : file_(file) {}

  // The bytes to hand OpenVDB's stream reader for the first float grid (the one copy of the
  // file's bytes).
  std::string cut() {
    if (u64() != std::uint64_t(openvdb::OPENVDB_MAGIC)) fail("not a .vdb file (no OpenVDB magic number)");
    const std::uint32_t version = u32();
    if (version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION || version > openvdb::OPENVDB_FILE_VERSION)
      fail("file format version " + std::to_string(version) + " is not one this server reads (222 to " +
           std::to_string(openvdb::OPENVDB_FILE_VERSION) + ")");
    skip(4 + 4);  // library major and minor
    offsets_ = byte() != 0;
    skip(36);  // UUID as 36 characters
    metaMap();
    countAt_ = at_;
    grids_ = std::int32_t(u32());
    if (grids_ < 0 || std::uint64_t(grids_) > left() / 40) fail("declares " + std::to_string(grids_) + " grids");
    if (grids_ == 0) fail("holds no float grid");
    for (std::int32_t i = 0; i < grids_; ++i) {
      const Descriptor d = descriptor(i);
      const bool isFloat =
          d.type == openvdb::FloatGrid::gridType() || d.type == openvdb::FloatGrid::gridType() + "_HalfFloat";
      if (isFloat || !offsets_) {
        if (!isFloat)
          fail("its first grid holds " + std::string(d.type) + ", not floats, and without grid offsets no later grid can be found");
        floatAt_ = d.at;
        floatIndex_ = i;
        return gridBytes(d);
      }
      at_ = std::size_t(d.end);
    }
    fail("holds no float grid");
  }

  // After cut(): the bytes for the colour grid, or empty when the file has none. `readTo` is
  // where OpenVDB stopped reading in the bytes cut() gave, the end of the float grid's tree.
  std::string cutColor(std::size_t readTo) {
    if (offsets_) {
      at_ = countAt_ + 4;
      for (std::int32_t i = 0; i < grids_; ++i) {
        const Descriptor d = descriptor(i);
        if (isColor(d)) return gridBytes(d);
        at_ = std::size_t(d.end);
      }
      return {};
    }
    if (floatIndex_ + 1 >= grids_) return {};
    at_ = floatAt_ + (readTo - (countAt_ + 4));
    // Another grid's descriptor is not this reader's to check: only a grid named "color" is read.
    const std::string_view name(kColorGridName);
    if (left() < 4 + name.size() || u32() != name.size() || file_.substr(at_, name.size()) != name) return {};
    at_ -= 4;
    const Descriptor d = descriptor(floatIndex_ + 1);
    return isColor(d) ? gridBytes(d) : std::string();
  }

 private:
  struct Descriptor {
    std::size_t at;
    std::string_view name, type;
    std::uint64_t end;
  };
  // The descriptor at at_ (of grid i), read up to its end offset.
  Descriptor descriptor(std::int32_t i) {
    Descriptor d{at_, {}, {}, 0};
    d.name = string();  // unique name
    d.type = string();
    string();  // instance parent
    skip(8 + 8);  // grid and block offsets
    d.end = u64();
    if (offsets_ && (d.end <= at_ || d.end > file_.size()))
      fail("grid " + std::to_string(i) + "'s end offset lies outside the file");
    return d;
  }
  static bool isColor(const Descriptor& d) {
    return d.name == kColorGridName && d.type == openvdb::Vec3SGrid::gridType();
  }
  // The header, a grid count of 1 and grid d, whose metadata lengths are checked first.
  std::string gridBytes(const Descriptor& d) {
    skip(4);  // the grid's compression flags
    metaMap();
    string();  // the transform's map type
    const std::string_view grid = file_.substr(d.at, offsets_ ? std::size_t(d.end) - d.at : std::string_view::npos);
    std::string out;
    out.reserve(countAt_ + 4 + grid.size());
    out.append(file_.substr(0, countAt_));
    for (int b = 0; b < 4; ++b) out.push_back(char(b == 0 ? 1 : 0));
    out.append(grid);
    return out;
  }

 private:
  [[noreturn]] static void fail(const std::string& what) {
    throw EngineError(ErrorKind::Format, "file", "not a readable .vdb file: " + what);
  }
  std::uint64_t left() const { return file_.size() - at_; }
  void skip(std::uint64_t n) {
    if (n > left()) fail("it ends inside its header or metadata");
    at_ += std::size_t(n);
  }
  std::uint64_t read(int bytes) {
    if (std::uint64_t(bytes) > left()) fail("it ends inside its header or metadata");
    std::uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) v = v << 8 | std::uint8_t(file_[at_ + std::size_t(i)]);
    at_ += std::size_t(bytes);
    return v;
  }
  std::uint8_t byte() { return std::uint8_t(read(1)); }
  std::uint32_t u32() { return std::uint32_t(read(4)); }
  std::uint64_t u64() { return read(8); }
  std::string_view string() {
    const std::uint32_t n = u32();
    if (n > left()) fail("a name declares " + std::to_string(n) + " bytes, more than the file holds");
    const std::string_view s = file_.substr(at_, n);
    at_ += n;
    return s;
  }
  void metaMap() {
    const std::uint32_t count = u32();
    if (count > left() / 12) fail("declares " + std::to_string(count) + " metadata entries");
    for (std::uint32_t i = 0; i < count; ++i) {
      string();  // name
      string();  // type name
      const std::uint32_t n = u32();
      if (n > left()) fail("a metadata value declares " + std::to_string(n) + " bytes, more than the file holds");
      skip(n);
    }
  }

  std::string_view file_;
  std::size_t at_ = 0;
  bool offsets_ = false;
  std::size_t countAt_ = 0, floatAt_ = 0;
  std::int32_t grids_ = 0, floatIndex_ = 0;
};

// A read-only stream buffer over bytes held elsewhere, seekable like an istringstream's (which
// would copy them).
class ViewBuf : public std::streambuf {
 public:
  explicit ViewBuf(std::string_view s) {
    char* p = const_cast<char*>(s.data());
    setg(p, p, p + s.size());
  }
  // The bytes read so far.
  std::size_t consumed() const { return std::size_t(gptr() - eback()); }

 protected:
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override {
    if (!(which & std::ios_base::in)) return pos_type(off_type(-1));
    const off_type size = egptr() - eback();
    const off_type base = dir == std::ios_base::beg ? 0 : dir == std::ios_base::cur ? gptr() - eback() : size;
    if (off < -base || off > size - base) return pos_type(off_type(-1));
    setg(eback(), eback() + (base + off), egptr());
    return pos_type(base + off);
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode which) override {
    return seekoff(off_type(pos), std::ios_base::beg, which);
  }
};

}  // namespace

void saveVdb(const Volume& vol, const std::string& path) {
  const openvdb::GridPtrVec grids = gridsOf(vol);
  try {
    openvdb::io::File file(path);
    file.write(grids);
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::InvalidArgument, "path", std::string("cannot write ") + path + ": " + e.what());
  }
}

void saveVdb(const Volume& vol, std::ostream& out) {
  openvdb::io::Stream(out).write(gridsOf(vol));
}

Volume loadVdb(const std::string& path, Int3 dims, float band) {
  initialize();
  auto grids = std::make_shared<openvdb::GridPtrVec>();
  openvdb::Vec3SGrid::Ptr color;
  try {
    openvdb::io::File file(path);
    file.open();
    for (auto it = file.beginName(); it != file.endName() && grids->empty(); ++it) {
      auto grid = file.readGrid(it.gridName());
      if (openvdb::gridPtrCast<openvdb::FloatGrid>(grid)) grids->push_back(grid);
    }
    if (file.hasGrid(kColorGridName)) color = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid(kColorGridName));
    file.close();
  } catch (const openvdb::Exception& e) {
    throw EngineError(ErrorKind::Format, "file", std::string("cannot read ") + path + ": " + e.what());
  }
  Volume vol = volumeOf(grids, dims, band, path, SIZE_MAX);
  if (color) takeColors(vol, *color, path);
  return vol;
}

Volume loadVdb(std::istream& in, Int3 dims, float band) {
  const std::string file{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  return loadVdb(std::span(reinterpret_cast<const std::uint8_t*>(file.data()), file.size()), dims, band);
}

Volume loadVdb(std::span<const std::uint8_t> file, Int3 dims, float band, std::size_t maxBytes) {
  initialize();
  GridCutter cutter(std::string_view(reinterpret_cast<const char*>(file.data()), file.size()));
  std::size_t readTo = 0;
  // OpenVDB's grids from bytes a GridCutter cut; readTo becomes where its reading stopped.
  auto read = [&](const std::string& cut) {
    ViewBuf buffer(cut);
    std::istream grid(&buffer);
    // A read past the end throws at once: OpenVDB's loops over declared counts (tiles, children)
    // would otherwise go on over a failed stream, allocating a node for each.
    grid.exceptions(std::ios::failbit | std::ios::badbit);
    try {
      // delayLoad = false: with delayed loading OpenVDB copies the stream into a temporary file.
      openvdb::GridPtrVecPtr grids = openvdb::io::Stream(grid, false).getGrids();
      readTo = buffer.consumed();
      return grids;
    } catch (const std::bad_alloc&) {
      // Sizes declared in the tree (node counts, compressed lengths) that no memory can hold.
      throw EngineError(ErrorKind::Format, "file", "not a readable .vdb file: it declares more data than the server can hold");
    } catch (const std::exception& e) {
      throw EngineError(ErrorKind::Format, "file", std::string("not a readable .vdb file: ") + e.what());
    }
  };
  Volume vol = volumeOf(read(cutter.cut()), dims, band, "the .vdb file", maxBytes);
  const std::string color = cutter.cutColor(readTo);
  if (color.empty()) return vol;
  const openvdb::GridPtrVecPtr grids = read(color);
  const auto grid = grids && !grids->empty() ? openvdb::gridPtrCast<openvdb::Vec3SGrid>(grids->front()) : nullptr;
  if (!grid) throw EngineError(ErrorKind::Format, "file", "not a readable .vdb file: its colour grid holds no colours");
  takeColors(vol, *grid, "the .vdb file");
  if (vol.memoryBytes() > maxBytes)
    throw EngineError(ErrorKind::TooLarge, "file",
                      "the .vdb file: its volume with its colours takes " + std::to_string(vol.memoryBytes()) +
                          " bytes, more than " + std::to_string(maxBytes));
  return vol;
}

}  // namespace marzipan
