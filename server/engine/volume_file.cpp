// The native volume file. Byte layout and validity rules: see volume_file.hpp.
// Validation order: size and magic, version, header values, exact file size, checksum, then
// every brick; nothing is allocated from a count before the file's size has confirmed it.
#include "volume_file.hpp"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "errors.hpp"
#include "little_endian.hpp"

namespace marzipan {

namespace {

constexpr std::uint8_t kMagic[4] = {'M', 'Z', 'V', 'F'};

using namespace le;

// 512 voxel values to or from little-endian bytes.
void putValues(std::uint8_t* p, const float* v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(p, v, sizeof(float) * kBrickVoxels);
  } else {
    for (int i = 0; i < kBrickVoxels; ++i) put32(p + 4 * i, std::bit_cast<std::uint32_t>(v[i]));
  }
}
void getValues(const std::uint8_t* p, float* v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(v, p, sizeof(float) * kBrickVoxels);
  } else {
    for (int i = 0; i < kBrickVoxels; ++i) v[i] = std::bit_cast<float>(get32(p + 4 * i));
  }
}

constexpr std::array<std::uint32_t, 256> makeCrcTable() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[i] = c;
  }
  return t;
}
constexpr auto kCrcTable = makeCrcTable();

[[noreturn]] void formatError(const std::string& message) { throw EngineError(ErrorKind::Format, "file", message); }

std::string brickName(Int3 b) {
  std::ostringstream s;
  s << "brick (" << b.x << ", " << b.y << ", " << b.z << ")";
  return s.str();
}

std::uint64_t orderKey(Int3 b) { return std::uint64_t(b.z) << 32 | std::uint64_t(b.y) << 16 | std::uint64_t(b.x); }

// The 8-byte brick address: u16 x, y, z, reserved 0.
void putAddress(std::uint8_t* p, Int3 b) {
  put16(p, std::uint32_t(b.x));
  put16(p + 2, std::uint32_t(b.y));
  put16(p + 4, std::uint32_t(b.z));
  put16(p + 6, 0);
}

// Reads the 8-byte brick address (u16 x, y, z, reserved) and checks it against the grid and
// the z, y, x order that makes files canonical. `what` ("stored", "inside") names the section.
Int3 readAddress(const std::uint8_t* p, Int3 grid, std::uint64_t& lastKey, bool& first, const char* what) {
  const Int3 b{int(get16(p)), int(get16(p + 2)), int(get16(p + 4))};
  if (get16(p + 6) != 0)
    formatError("reserved bytes of the address of " + std::string(what) + " " + brickName(b) + " must be 0");
  if (b.x >= grid.x || b.y >= grid.y || b.z >= grid.z)
    formatError(std::string(what) + " " + brickName(b) + " is outside the brick grid " + std::to_string(grid.x) + "x" +
                std::to_string(grid.y) + "x" + std::to_string(grid.z));
  const std::uint64_t key = orderKey(b);
  if (!first && key <= lastKey)
    formatError(std::string(what) + " " + brickName(b) + " is out of z, y, x order or listed twice");
  first = false;
  lastKey = key;
  return b;
}

// Version 2 is written only for what version 1 cannot hold.
bool withChannels(const Volume& vol) { return vol.paintedBricks() != 0 || vol.baseColor() != kClayColor; }

}  // namespace

std::uint32_t crc32Ieee(std::span<const std::uint8_t> bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (const std::uint8_t b : bytes) c = kCrcTable[(c ^ b) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::size_t savedVolumeSize(const Volume& vol) {
  std::size_t inside = 0;
  vol.forEachInsideBrick([&](Int3) { ++inside; });
  return kVolumeFileHeaderBytes + kVolumeFileBrickBytes * vol.presentBricks() + kVolumeFileInsideBytes * inside +
         (withChannels(vol) ? kVolumeFileBaseColorBytes + kVolumeFilePaintBytes * vol.paintedBricks() : 0) +
         kVolumeFileTrailerBytes;
}

std::vector<std::uint8_t> saveVolume(const Volume& vol) {
  std::vector<Int3> inside;
  vol.forEachInsideBrick([&](Int3 b) { inside.push_back(b); });
  const std::size_t present = vol.presentBricks();
  const bool channels = withChannels(vol);
  std::vector<std::uint8_t> out(savedVolumeSize(vol));
  std::uint8_t* p = out.data();
  std::memcpy(p, kMagic, 4);
  put32(p + 4, channels ? 2 : 1);
  const Int3 d = vol.dims();
  put32(p + 8, std::uint32_t(d.x));
  put32(p + 12, std::uint32_t(d.y));
  put32(p + 16, std::uint32_t(d.z));
  put32(p + 20, std::bit_cast<std::uint32_t>(vol.band()));
  put64(p + 24, vol.revision());
  put32(p + 32, kBrickSide);
  put32(p + 36, std::uint32_t(present));
  put32(p + 40, std::uint32_t(inside.size()));
  put32(p + 44, std::uint32_t(vol.paintedBricks()));
  p += kVolumeFileHeaderBytes;
  vol.forEachPresentBrick([&](Int3 b, const Brick& br) {
    putAddress(p, b);
    putValues(p + 8, br.v);
    p += kVolumeFileBrickBytes;
  });
  for (const Int3& b : inside) {
    putAddress(p, b);
    p += kVolumeFileInsideBytes;
  }
  if (channels) {
    const Rgb8 base = vol.baseColor();
    p[0] = base.r, p[1] = base.g, p[2] = base.b, p[3] = 0;
    p += kVolumeFileBaseColorBytes;
    vol.forEachPaintedBrick([&](Int3 b, const BrickPaint& bp) {
      putAddress(p, b);
      for (int i = 0; i < kBrickVoxels; ++i) {
        const Texel t = bp.t[i];
        p[8 + 4 * i] = t.r, p[9 + 4 * i] = t.g, p[10 + 4 * i] = t.b, p[11 + 4 * i] = t.mask;
      }
      p += kVolumeFilePaintBytes;
    });
  }
  put32(p, crc32Ieee({out.data(), out.size() - kVolumeFileTrailerBytes}));
  return out;
}

Volume loadVolume(std::span<const std::uint8_t> bytes) {
  const std::size_t size = bytes.size();
  const std::uint8_t* p = bytes.data();
  constexpr std::size_t kMinSize = kVolumeFileHeaderBytes + kVolumeFileTrailerBytes;
  if (size < kMinSize)
    formatError("truncated: " + std::to_string(size) + " bytes, a volume file has at least " +
                std::to_string(kMinSize));
  if (std::memcmp(p, kMagic, 4) != 0) formatError("not a Marzipan volume file (wrong magic bytes)");
  const std::uint32_t version = get32(p + 4);
  if (version != 1 && version != 2)
    formatError("unsupported format version " + std::to_string(version) + " (this build reads versions 1 to " +
                std::to_string(kVolumeFileVersion) + ")");

  Int3 dims;
  for (int a = 0; a < 3; ++a) {
    const std::uint32_t v = get32(p + 8 + 4 * a);
    if (v < std::uint32_t(kBrickSide) || v > std::uint32_t(kMaxDomainSide))
      formatError("dimension " + std::to_string(v) + " is outside [8, 1024]");
    dims[a] = int(v);
  }
  const float band = std::bit_cast<float>(get32(p + 20));
  if (!(band >= 2.0f && band <= 8.0f)) formatError("band half-width must be in [2, 8]");
  const std::uint64_t revision = get64(p + 24);
  if (get32(p + 32) != std::uint32_t(kBrickSide))
    formatError("brick side " + std::to_string(get32(p + 32)) + " (this build uses " + std::to_string(kBrickSide) + ")");
  if (version == 1 && get32(p + 44) != 0) formatError("reserved header bytes must be 0");
  const Int3 grid = Bricks::gridOf(dims);
  const std::uint64_t slots = std::uint64_t(grid.x) * std::uint64_t(grid.y) * std::uint64_t(grid.z);
  const std::uint64_t present = get32(p + 36), inside = get32(p + 40), painted = version == 2 ? get32(p + 44) : 0;
  if (present + inside > slots)
    formatError(std::to_string(present) + " stored and " + std::to_string(inside) + " inside bricks exceed the " +
                std::to_string(slots) + " bricks of the grid");
  if (painted > present)
    formatError(std::to_string(painted) + " painted bricks exceed the " + std::to_string(present) + " stored ones");
  const std::uint64_t expected =
      kVolumeFileHeaderBytes + kVolumeFileBrickBytes * present + kVolumeFileInsideBytes * inside +
      (version == 2 ? kVolumeFileBaseColorBytes + kVolumeFilePaintBytes * painted : 0) + kVolumeFileTrailerBytes;
  if (std::uint64_t(size) != expected)
    formatError("size mismatch: the header describes " + std::to_string(present) + " stored, " +
                std::to_string(inside) + " inside and " + std::to_string(painted) + " painted bricks, " +
                std::to_string(expected) + " bytes; the file has " + std::to_string(size) +
                (std::uint64_t(size) < expected ? " (truncated)" : " (trailing bytes)"));
  const std::uint32_t stored = get32(p + size - kVolumeFileTrailerBytes);
  const std::uint32_t computed = crc32Ieee({p, size - kVolumeFileTrailerBytes});
  if (stored != computed) formatError("checksum mismatch: the file is corrupted");

  Volume vol(dims, band);
  std::vector<BrickChange> changes;
  changes.reserve(std::size_t(present + inside));
  std::vector<std::uint8_t> seen(std::size_t(slots), 0);
  auto slot = [&](Int3 b) {
    return std::size_t(b.x) + std::size_t(grid.x) * (std::size_t(b.y) + std::size_t(grid.y) * std::size_t(b.z));
  };
  std::size_t at = kVolumeFileHeaderBytes;
  std::uint64_t lastKey = 0;
  bool first = true;
  for (std::uint64_t i = 0; i < present; ++i, at += kVolumeFileBrickBytes) {
    const Int3 b = readAddress(p + at, grid, lastKey, first, "stored");
    seen[slot(b)] = 1;
    auto br = std::make_shared<Brick>();
    getValues(p + at + 8, br->v);
    for (const float v : br->v)
      if (!(std::fabs(v) <= band)) formatError(brickName(b) + " holds a value that is NaN or outside +-band");
    for (int k = 0; k < kBrickVoxels; ++k) {
      const Int3 v = Bricks::origin(b) + Bricks::local(k);
      const bool past = v.x >= dims.x || v.y >= dims.y || v.z >= dims.z;
      if (past && br->v[k] != band) formatError(brickName(b) + " holds a voxel past the domain's edge that is not +band");
    }
    // Volume keeps such a brick as a uniform slot; storing it would give the same field another
    // digest than it has when built any other way.
    BrickRef ref = vol.canonicalBrick(b, std::move(br));
    if (!ref.data)
      formatError(brickName(b) + " is stored but uniformly " + (ref.inside ? "inside" : "outside") +
                  " (list it as inside or leave it out)");
    changes.push_back({b, {}, std::move(ref)});
  }
  first = true;
  for (std::uint64_t i = 0; i < inside; ++i, at += kVolumeFileInsideBytes) {
    const Int3 b = readAddress(p + at, grid, lastKey, first, "inside");
    if (seen[slot(b)]) formatError(brickName(b) + " is listed both as stored and as inside");
    changes.push_back({b, {}, BrickRef{nullptr, true}});
  }
  if (version == 2) {
    const std::uint8_t* c = p + at;
    if (c[3] != 0) formatError("the reserved byte of the base colour must be 0");
    vol.setBaseColor({c[0], c[1], c[2]});
    at += kVolumeFileBaseColorBytes;
    // The stored bricks' changes are the first `present`, in the same z, y, x order.
    std::size_t next = 0;
    first = true;
    for (std::uint64_t i = 0; i < painted; ++i, at += kVolumeFilePaintBytes) {
      const Int3 b = readAddress(p + at, grid, lastKey, first, "painted");
      while (next < present && orderKey(changes[next].brick) < orderKey(b)) ++next;
      if (next == present || changes[next].brick != b) formatError("painted " + brickName(b) + " is not a stored brick");
      auto bp = std::make_shared<BrickPaint>();
      for (int k = 0; k < kBrickVoxels; ++k) {
        const std::uint8_t* t = p + at + 8 + 4 * k;
        bp->t[k] = {t[0], t[1], t[2], t[3]};
      }
      changes[next].after.paint = vol.canonicalPaint(std::move(bp));
      if (!changes[next].after.paint)
        formatError("painted " + brickName(b) + " holds only the base colour with weight 0 (leave it out)");
    }
  }
  vol.publish(changes, true);
  vol.setRevision(revision);
  return vol;
}

void saveVolumeFile(const Volume& vol, const std::string& path) {
  const auto bytes = saveVolume(vol);
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    f.close();
    if (!f) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw EngineError(ErrorKind::InvalidArgument, "path", "cannot write " + tmp);
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw EngineError(ErrorKind::InvalidArgument, "path", "cannot rename " + tmp + " to " + path + ": " + ec.message());
  }
}

Volume loadVolumeFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) throw EngineError(ErrorKind::InvalidArgument, "path", "cannot open " + path);
  const std::streamoff size = f.tellg();
  if (size < 0) throw EngineError(ErrorKind::InvalidArgument, "path", "cannot read " + path);
  // The largest valid file: every brick of a 1024^3 grid stored and painted.
  constexpr std::uint64_t kMaxSlots =
      std::uint64_t(kMaxDomainSide / kBrickSide) * (kMaxDomainSide / kBrickSide) * (kMaxDomainSide / kBrickSide);
  if (std::uint64_t(size) > kVolumeFileHeaderBytes + (kVolumeFileBrickBytes + kVolumeFilePaintBytes) * kMaxSlots +
                                kVolumeFileBaseColorBytes + kVolumeFileTrailerBytes)
    formatError(path + " is larger than any volume file");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  f.seekg(0);
  f.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!f) throw EngineError(ErrorKind::InvalidArgument, "path", "cannot read " + path);
  return loadVolume(bytes);
}

}  // namespace marzipan
