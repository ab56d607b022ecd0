// Writes the seed corpora of the fuzz targets: the golden vectors of the protocol
// (tests/protocol/vectors/vectors.json) and small valid files made by the engine itself, plus
// one seed per hostile input of the README's "Bad input" table. Nothing binary is committed:
// tests/fuzz/run.sh runs this before fuzzing.
//
// Usage: marzipan_fuzz_seeds VECTORS_JSON OUT_DIR
// Writes OUT_DIR/<target>/<name> for the targets frame_header, op, rpc, volume_file, splats,
// stl, obj and ply (directories are created; existing files are overwritten).
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/little_endian.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/mesh_io.hpp"
#include "engine/paint.hpp"
#include "engine/solids.hpp"
#include "engine/splats.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/splats.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace marzipan;

namespace {

fs::path outDir;

void write(const std::string& target, const std::string& name, const void* data, std::size_t size) {
  const fs::path dir = outDir / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out.write(static_cast<const char*>(data), std::streamsize(size));
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}
void write(const std::string& target, const std::string& name, const std::vector<std::uint8_t>& bytes) {
  write(target, name, bytes.data(), bytes.size());
}
void write(const std::string& target, const std::string& name, std::string_view text) {
  write(target, name, text.data(), text.size());
}

// Vector names become file names: letters and digits kept, anything else one '_'.
std::string fileName(std::string_view prefix, std::size_t index, std::string_view name) {
  std::string out = std::string(prefix) + "-" + std::to_string(index) + "-";
  for (const char c : name) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    if (keep) out += c;
    else if (out.back() != '_') out += '_';
  }
  return out;
}

std::vector<std::uint8_t> fromHex(const std::string& hex) {
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) out.push_back(std::uint8_t(std::stoul(hex.substr(i, 2), nullptr, 16)));
  return out;
}

void protocolSeeds(const json& v) {
  std::size_t i = 0;
  for (const char* section : {"binary", "binary_invalid"})
    for (const json& b : v.at(section)) write("frame_header", fileName(section, i++, b.at("name").get<std::string>()), fromHex(b.at("hex")));
  const std::vector<std::uint8_t> payload{1, 2, 3};
  for (std::uint16_t kind = protocol::kMinFrameKind; kind <= protocol::kMaxFrameKind; ++kind)
    write("frame_header", "kind-" + std::to_string(kind), protocol::encodeFrame(protocol::FrameKind(kind), kind, 7, payload));

  i = 0;
  for (const json& o : v.at("ops").at("valid")) {
    write("op", fileName("valid", i, "op"), o.at("op").dump());
    write("op", fileName("canonical", i++, "op"), o.at("canonical").dump());
  }
  for (const json& o : v.at("ops").at("invalid")) write("op", fileName("invalid", i++, o.at("name").get<std::string>()), o.at("op").dump());

  i = 0;
  for (const char* section : {"requests", "responses", "errors", "notifications", "invalid_requests"})
    for (const json& m : v.at(section))
      write("rpc", fileName(section, i++, m.at("name").get<std::string>()), m.at("text").get<std::string>());
}

// A closed tetrahedron, counter-clockwise seen from outside, well inside a 16^3 domain.
Mesh tetrahedron() {
  Mesh m;
  m.positions = {3, 3, 3, 12, 3, 3, 3, 12, 3, 3, 3, 12};
  m.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

void engineSeeds() {
  const Volume sphere = makeSolid(SolidKind::Sphere, {8, 8, 8});
  const Volume torus = makeSolid(SolidKind::Torus, {12, 9, 17});  // bricks past the domain's edge
  const Volume box = makeSolid(SolidKind::Box, {24, 24, 24});      // inside bricks
  write("volume_file", "empty-8", saveVolume(makeSolid(SolidKind::Empty, {8, 8, 8})));
  write("volume_file", "sphere-8", saveVolume(sphere));
  write("volume_file", "torus-12x9x17", saveVolume(torus));
  write("volume_file", "box-24", saveVolume(box));

  write("splats", "empty", encodeSplats({}, kSplatFormatVersionPlain));
  write("splats", "sphere-8", encodeSplats(extractAllSplats(sphere), kSplatFormatVersionPlain));
  write("splats", "torus-delta", encodeSplats(extractSplats(torus, {{0, 0, 0}, {1, 0, 1}}), kSplatFormatVersionPlain));
  Volume painted = makeSolid(SolidKind::Sphere, {16, 16, 16});
  PaintSettings red;
  red.color = {200, 20, 10};
  red.radius = 5;
  paint(painted, red, {12, 8, 8});
  red.mode = PaintMode::MaskAdd;
  paint(painted, red, {8, 12, 8});
  write("splats", "v2-empty", encodeSplats({}, 2));
  write("splats", "v2-painted-sphere-16", encodeSplats(extractAllSplats(painted), 2));

  const Mesh tetra = tetrahedron();
  const Mesh ball = extractMesh(sphere);
  Mesh withNormals = ball;
  withNormals.normals.assign(ball.positions.size(), 0.0f);
  for (std::size_t k = 2; k < withNormals.normals.size(); k += 3) withNormals.normals[k] = 1;
  write("stl", "tetrahedron", exportStl(tetra));
  write("stl", "sphere-8", exportStl(ball));
  write("stl", "tetrahedron-ascii",
        "solid t\n"
        "facet normal 0 0 -1\n outer loop\n  vertex 3 3 3\n  vertex 3 12 3\n  vertex 12 3 3\n endloop\nendfacet\n"
        "facet normal 0 -1 0\n outer loop\n  vertex 3 3 3\n  vertex 12 3 3\n  vertex 3 3 12\n endloop\nendfacet\n"
        "facet normal -1 0 0\n outer loop\n  vertex 3 3 3\n  vertex 3 3 12\n  vertex 3 12 3\n endloop\nendfacet\n"
        "facet normal 1 1 1\n outer loop\n  vertex 12 3 3\n  vertex 3 12 3\n  vertex 3 3 12\n endloop\nendfacet\n"
        "endsolid t\n");
  write("obj", "tetrahedron", exportObj(tetra));
  write("obj", "sphere-8-normals", exportObj(withNormals));
  write("obj", "quads-negative-indices",
        "# a cube of quads, indices counted back from the last vertex\n"
        "o cube\nv 2 2 2\nv 10 2 2\nv 10 10 2\nv 2 10 2\nv 2 2 10\nv 10 2 10\nv 2 10 10\nv 10 10 10\n"
        "vt 0 0\ns off\nf -8 -5 -6 -7\nf 5/1 6/1 8/1 7/1\nf -8 -7 -3 -4\nf -6 -5 -2 -1\nf -8 -4 -2 -5\nf -7 -6 -1 -3\n");
  write("ply", "tetrahedron", exportPly(tetra));
  write("ply", "sphere-8-normals", exportPly(withNormals));
  write("ply", "tetrahedron-mixed-types",
        [] {
          std::string h =
              "ply\nformat binary_little_endian 1.0\ncomment types other than float\nelement vertex 4\n"
              "property double x\nproperty short y\nproperty uchar z\nelement edge 1\nproperty int a\n"
              "element face 4\nproperty list uchar int vertex_indices\nend_header\n";
          std::vector<std::uint8_t> b(h.begin(), h.end());
          const Mesh t = tetrahedron();
          for (std::size_t v = 0; v < 4; ++v) {
            const double x = t.positions[3 * v];
            std::uint8_t d[8];
            std::memcpy(d, &x, 8);
            b.insert(b.end(), d, d + 8);
            b.push_back(std::uint8_t(t.positions[3 * v + 1]));
            b.push_back(0);
            b.push_back(std::uint8_t(t.positions[3 * v + 2]));
          }
          le::append32(b, 0);
          for (std::size_t f = 0; f < 4; ++f) {
            b.push_back(3);
            for (int k = 0; k < 3; ++k) le::append32(b, t.indices[3 * f + std::size_t(k)]);
          }
          return std::string(b.begin(), b.end());
        }());
}

// Hostile inputs of the README's "Bad input" table that the vectors do not already hold.
void badInputSeeds() {
  std::vector<std::uint8_t> stl(84, 0);
  le::put32(stl.data() + 80, 0xFFFFFFFFu);  // an 84-byte file claiming 2^32 - 1 triangles
  write("stl", "bad-absurd-triangle-count", stl);
  write("stl", "bad-four-vertex-facet",
        "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nvertex 1 1 0\n");
  write("ply", "bad-huge-vertex-count",
        "ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
  write("obj", "bad-index-out-of-range", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  write("obj", "bad-nan-coordinate", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");

  std::vector<std::uint8_t> mzv = saveVolume(makeSolid(SolidKind::Sphere, {8, 8, 8}));
  auto truncated = mzv;
  truncated.resize(mzv.size() - 100);
  write("volume_file", "bad-truncated", truncated);
  auto flipped = mzv;
  flipped[100] ^= 1;
  write("volume_file", "bad-crc-mismatch", flipped);
  std::vector<std::uint8_t> huge(kVolumeFileHeaderBytes + kVolumeFileTrailerBytes, 0);
  std::memcpy(huge.data(), mzv.data(), kVolumeFileHeaderBytes);
  le::put32(huge.data() + 36, 0xFFFFFFFFu);  // 2^32 - 1 stored bricks in a 52-byte file
  le::put32(huge.data() + kVolumeFileHeaderBytes, crc32Ieee({huge.data(), kVolumeFileHeaderBytes}));
  write("volume_file", "bad-huge-brick-count", huge);
  auto uniform = mzv;  // the sphere's one stored brick, every voxel +band: stored but uniform
  for (std::size_t k = 0; k < std::size_t(kBrickVoxels); ++k)
    le::put32(uniform.data() + kVolumeFileHeaderBytes + 8 + 4 * k, std::bit_cast<std::uint32_t>(Volume::kDefaultBand));
  le::put32(uniform.data() + uniform.size() - 4, crc32Ieee({uniform.data(), uniform.size() - 4}));
  write("volume_file", "bad-uniform-stored-brick", uniform);

  std::vector<std::uint8_t> splats = encodeSplats({});
  le::put32(splats.data() + 8, 0xFFFFFFFFu);
  write("splats", "bad-huge-brick-count", splats);

  write("op", "bad-nan", R"({"tool":"add_blob","center":[NaN,0,0]})");
  write("op", "bad-huge-number", R"({"tool":"add_blob","center":[1e999,0,0]})");
  write("op", "bad-unterminated-string", R"({"tool":"add_blob","center":[0,0,0],"x":")" + std::string(2000, 'x'));
  write("op", "bad-deep-nesting", std::string(5000, '[') + std::string(5000, ']'));
  write("rpc", "bad-unterminated-string", R"({"jsonrpc":"2.0","id":1,"method":")" + std::string(2000, 'm'));
  write("rpc", "bad-deep-nesting",
        R"({"jsonrpc":"2.0","id":1,"method":"tool.apply","params":{"tool":"add_blob","center":)" + std::string(5000, '[') +
            std::string(5000, ']') + "}}");
  write("rpc", "bad-not-utf8", "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"\xC3\x28\xFF\"}");
  write("rpc", "bad-id-2-53", R"({"jsonrpc":"2.0","id":9007199254740992,"method":"session.stats"})");
  write("rpc", "bad-upload-size", R"({"jsonrpc":"2.0","id":3,"method":"volume.load","params":{"bytes":9007199254740991}})");
  write("rpc", "bad-many-dabs",
        [] {
          std::string dabs;
          for (int k = 0; k < 300; ++k) dabs += std::string(k ? "," : "") + R"({"center":[1,2,3]})";
          return R"({"jsonrpc":"2.0","id":1,"method":"stroke.dabs","params":{"stroke":1,"dabs":[)" + dabs + "]}}";
        }());
  write("rpc", "bad-frame-side", R"({"jsonrpc":"2.0","id":2,"method":"render.frame","params":{"camera":{"eye":[0,0,100],"target":[0,0,0]},"width":100000,"height":8,"format":"png"}})");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s VECTORS_JSON OUT_DIR\n", argv[0]);
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  if (!in) {
    std::fprintf(stderr, "cannot read %s\n", argv[1]);
    return 1;
  }
  outDir = argv[2];
  protocolSeeds(json::parse(text.str()));
  engineSeeds();
  badInputSeeds();
  return 0;
}
