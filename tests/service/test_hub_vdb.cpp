// volume.save / volume.load with `format` (protocol 1.3). In a build with OpenVDB
// (MARZIPAN_HAS_OPENVDB) a session saved as .vdb is read back by OpenVDB itself and compared
// voxel by voxel with the session's .mzv, loaded into another session with the same digest, and
// hostile .vdb uploads (truncated, not a .vdb, a grid reaching outside the session, a grid of
// absurd extent, a non-float grid, a NaN) are refused with -32006 and change nothing. Without
// OpenVDB, "vdb" is refused with -32602 (field "format") and limits.volume_formats says so.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <span>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "engine/volume.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/frames.hpp"
#include "service/hub.hpp"
#include "hub_support.hpp"

#ifdef MARZIPAN_HAS_OPENVDB
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#endif

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;
using nlohmann::json;
using Bytes = std::vector<std::uint8_t>;

namespace {

HubOptions vdbOptions() {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  return o;
}

// The session: a 64^3 sphere with a blob added, so the band is not a symmetric shape.
const json kCreate = {{"size", {64, 64, 64}}, {"solid", "sphere"}};

// volume.save with `format`: the result and the file its frame carried (of the given kind).
std::pair<json, Bytes> save(TestClient& a, const std::string& format, protocol::FrameKind kind) {
  const int id = a.nextId;
  const json result = a.result("volume.save", {{"format", format}});
  const Bytes frame = std::get<Bytes>(a.link->at(a.link->waitFor([&](const auto& m) {
    const Bytes* b = std::get_if<Bytes>(&m);
    if (!b) return false;
    const auto d = protocol::decodeFrameHeader(*b);
    return d && d.frame->header.kind == kind && d.frame->header.requestId == std::uint32_t(id);
  })));
  return {result, Bytes(frame.begin() + protocol::kFrameHeaderBytes, frame.end())};
}

// volume.load of `file` announced as `format`: the whole response.
json load(TestClient& a, std::span<const std::uint8_t> file, const std::string& format) {
  const int id = a.nextId++;
  a.hub.text(a.client, json{{"jsonrpc", "2.0"},
                            {"id", id},
                            {"method", "volume.load"},
                            {"params", {{"bytes", file.size()}, {"format", format}}}}
                           .dump());
  a.hub.binary(a.client, protocol::encodeFrame(protocol::FrameKind::VolumeUpload, std::uint32_t(id), 0, file));
  return std::get<json>(a.link->at(a.link->waitFor([&](const auto& m) { return isResponse(m, id); })));
}

}  // namespace

TEST_CASE("volume.save and volume.load take a format: mzv by default, others refused", "[hub][vdb]") {
  Hub hub(vdbOptions());
  TestClient a(hub);
  a.result("session.create", kCreate);
  const auto [result, file] = save(a, "mzv", protocol::FrameKind::VolumeFile);
  CHECK(result["format"] == "mzv");
  CHECK(file.size() == result["bytes"].get<std::size_t>());
  CHECK(a.result("volume.save")["format"] == "mzv");
  for (const json& bad : {json("stl"), json("VDB"), json(3)}) {
    const json r = a.call("volume.save", {{"format", bad}});
    CHECK(r["error"]["code"] == -32602);
    CHECK(r["error"]["data"]["field"] == "format");
    const json l = a.call("volume.load", {{"bytes", 100}, {"format", bad}});
    CHECK(l["error"]["code"] == -32602);
    CHECK(l["error"]["data"]["field"] == "format");
  }
  // An explicit "mzv" load is the load of 1.2.
  CHECK(load(a, file, "mzv")["result"]["digest"] == result["digest"]);
}

#ifdef MARZIPAN_HAS_OPENVDB

namespace {

// The grids of a .vdb file, read by OpenVDB from memory.
openvdb::GridPtrVecPtr readGrids(const Bytes& file) {
  openvdb::initialize();
  std::istringstream in(std::string(file.begin(), file.end()), std::ios::binary);
  return openvdb::io::Stream(in, false).getGrids();
}

Bytes vdbBytes(const openvdb::GridPtrVec& grids) {
  openvdb::initialize();
  std::ostringstream out(std::ios::binary);
  openvdb::io::Stream(out).write(grids);
  const std::string s = std::move(out).str();
  return Bytes(s.begin(), s.end());
}

}  // namespace

TEST_CASE("a session saved as .vdb holds its distances over the whole band and loads back exactly",
          "[hub][vdb][openvdb]") {
  Hub hub(vdbOptions());
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  CHECK(created["limits"]["volume_formats"] == json{"mzv", "vdb"});
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  const auto [mzvResult, mzv] = save(a, "mzv", protocol::FrameKind::VolumeFile);
  const auto [vdbResult, vdb] = save(a, "vdb", protocol::FrameKind::VolumeVdb);
  CHECK(vdbResult["format"] == "vdb");
  CHECK(vdbResult["digest"] == mzvResult["digest"]);
  CHECK(vdb.size() == vdbResult["bytes"].get<std::size_t>());

  // OpenVDB reads it: one level-set FloatGrid whose value at every voxel of the domain is the
  // session's distance (the .mzv's), active exactly where |d| < band.
  const Volume session = loadVolume(mzv);
  const openvdb::GridPtrVecPtr grids = readGrids(vdb);
  REQUIRE(grids->size() == 1);
  const auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
  REQUIRE(grid);
  CHECK(grid->getName() == "surface");
  CHECK(grid->getGridClass() == openvdb::GRID_LEVEL_SET);
  CHECK(grid->background() == session.band());
  CHECK(grid->voxelSize() == openvdb::Vec3d(1, 1, 1));
  auto acc = grid->getConstAccessor();
  double worst = 0;
  std::size_t band = 0, activeInBand = 0;
  const Int3 d = session.dims();
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        const float v = session.at(x, y, z);
        const openvdb::Coord c(x, y, z);
        worst = std::max(worst, double(std::fabs(acc.getValue(c) - v)));
        if (std::fabs(v) < session.band()) {
          ++band;
          activeInBand += acc.isValueOn(c) ? 1 : 0;
        }
      }
  CHECK(worst == 0.0);  // the band's floats are copied as they are (the bar is 1e-4 vu)
  CHECK(band > 20000);
  CHECK(activeInBand == band);
  CHECK(grid->activeVoxelCount() == band);

  // The stream layout is also what io::File (Blender's and Houdini's reader) opens from disk.
  const std::filesystem::path path = std::filesystem::temp_directory_path() / "marzipan-test-hub-vdb.vdb";
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(vdb.data()), std::streamsize(vdb.size()));
  }
  openvdb::io::File file(path.string());
  file.open();
  const auto fromFile = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
  file.close();
  std::filesystem::remove(path);
  REQUIRE(fromFile);
  CHECK(fromFile->activeVoxelCount() == band);
  CHECK(fromFile->tree().hasSameTopology(grid->tree()));

  // Loaded into another session of the same size: the same digest as the original (and as the
  // .mzv round trip), one undo step.
  TestClient b(hub);
  b.result("session.create", kCreate);
  const json fromVdb = load(b, vdb, "vdb");
  INFO(fromVdb.dump());
  CHECK(fromVdb["result"]["digest"] == mzvResult["digest"]);
  CHECK(fromVdb["result"]["can_undo"] == true);
  TestClient c(hub);
  c.result("session.create", kCreate);
  CHECK(load(c, mzv, "mzv")["result"]["digest"] == fromVdb["result"]["digest"]);
  b.result("history.undo");
  CHECK(b.result("session.stats")["digest"] != mzvResult["digest"]);
}

TEST_CASE("a session loaded from a .vdb comes back from the data directory after a restart", "[hub][vdb][openvdb]") {
  const auto dir = std::filesystem::temp_directory_path() / "marzipan-hub-vdb-restart";
  std::filesystem::remove_all(dir);
  HubOptions o = vdbOptions();
  o.dataDir = dir;
  json created, loaded;
  {
    Hub hub(o);
    TestClient a(hub);
    created = a.result("session.create", kCreate);
    a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
    const auto [saved, vdb] = save(a, "vdb", protocol::FrameKind::VolumeVdb);
    a.result("history.undo");
    loaded = load(a, vdb, "vdb");
    INFO(loaded.dump());
    CHECK(loaded["result"]["digest"] == saved["digest"]);
  }
  Hub again(o);
  TestClient b(again);
  const json joined = b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  CHECK(joined["digest"] == loaded["result"]["digest"]);
  CHECK(joined["revision"] == loaded["result"]["revision"]);
  std::filesystem::remove_all(dir);
}

TEST_CASE("hostile .vdb uploads are refused with -32006 and change nothing", "[hub][vdb][openvdb]") {
  Hub hub(vdbOptions());
  TestClient a(hub);
  a.result("session.create", kCreate);
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  const auto [saved, vdb] = save(a, "vdb", protocol::FrameKind::VolumeVdb);
  const auto [mzvResult, mzv] = save(a, "mzv", protocol::FrameKind::VolumeFile);
  const json before = a.result("session.stats");

  const auto refused = [&](std::span<const std::uint8_t> file, const std::string& says) {
    const json r = load(a, file, "vdb");
    INFO(r.dump());
    CHECK(r["error"]["code"] == -32006);
    CHECK(r["error"]["data"]["field"] == "file");
    CHECK(r["error"]["message"].get<std::string>().find(says) != std::string::npos);
  };
  // Truncated anywhere (in the header, the metadata, the topology, the values), and bytes that
  // are not a .vdb at all (here a .mzv).
  for (const std::size_t keep : {std::size_t(60), vdb.size() / 3, vdb.size() / 2, vdb.size() - 1})
    refused(std::span(vdb.data(), keep), "not a readable .vdb");
  refused(mzv, "not a readable .vdb");

  // Lengths OpenVDB would trust (it sizes and fills a string before reading it): a grid name of
  // 2 GiB, 4 billion metadata entries or 2 billion grids in a few bytes, and a file version this
  // server does not read. The first 57 bytes are the saved file's header.
  const auto crafted = [&](std::initializer_list<std::uint32_t> words) {
    Bytes b(vdb.begin(), vdb.begin() + 57);
    for (const std::uint32_t w : words)
      for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(w >> (8 * i)));
    b.resize(b.size() + 64, 0);
    return b;
  };
  refused(crafted({0, 1, 0x7FFFFFF0u}), "a name declares 2147483632 bytes");
  refused(crafted({0xFFFFFFFFu}), "declares 4294967295 metadata entries");
  refused(crafted({0, 0x7FFFFFFFu}), "declares 2147483647 grids");
  Bytes oldVersion = vdb;
  oldVersion[8] = 221;
  refused(oldVersion, "file format version 221");

  // A level set centred on the origin (as OpenVDB's tools make them) reaches below 0.
  openvdb::initialize();
  const auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(10.f, openvdb::Vec3f(0, 0, 0), 1.f, 3.f);
  refused(vdbBytes({sphere}), "outside the session's");
  // A grid of absurd extent: one active tile of 4096^3 voxels far away; refused before any copy.
  auto far = openvdb::FloatGrid::create(3.f);
  far->tree().addTile(3, openvdb::Coord(1 << 28, 1 << 28, 1 << 28), -3.f, true);
  refused(vdbBytes({far}), "outside the session's");
  // No float grid: a vector grid.
  auto vectors = openvdb::Vec3SGrid::create();
  vectors->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1, 0, 0));
  refused(vdbBytes({vectors}), "its first grid holds Tree_vec3s");
  // A NaN inside the domain.
  auto nan = openvdb::FloatGrid::create(3.f);
  nan->tree().setValue(openvdb::Coord(5, 6, 7), std::numeric_limits<float>::quiet_NaN());
  refused(vdbBytes({nan}), "not a finite number");

  const json after = a.result("session.stats");
  CHECK(after["digest"] == before["digest"]);
  CHECK(after["revision"] == before["revision"]);
  // The session still takes a good .vdb after all that.
  CHECK(load(a, vdb, "vdb")["result"]["digest"] == saved["digest"]);
}

// OpenVDB allocates a file's tree before it can be checked: a .vdb upload is bounded by its own
// limit, refused when announced, before a byte of it is buffered for reading.
TEST_CASE("a .vdb upload over max_vdb_bytes is refused when announced", "[hub][vdb][openvdb]") {
  Bytes vdb;
  {
    Hub hub(vdbOptions());
    TestClient a(hub);
    a.result("session.create", kCreate);
    vdb = save(a, "vdb", protocol::FrameKind::VolumeVdb).second;
    CHECK(a.result("session.stats")["revision"] == 0);
  }
  HubOptions o = vdbOptions();
  o.limits.maxVdbBytes = vdb.size() - 1;
  Hub hub(o);
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  CHECK(created["limits"]["max_vdb_bytes"] == vdb.size() - 1);
  a.result("tool.apply", {{"tool", "add_blob"}, {"center", {32, 54, 32}}});
  const json before = a.result("session.stats");
  const json r = load(a, vdb, "vdb");
  INFO(r.dump());
  CHECK(r["error"]["code"] == -32004);
  CHECK(r["error"]["data"]["limit"] == "max_vdb_bytes");
  CHECK(r["error"]["data"]["value"] == vdb.size());
  CHECK(r["error"]["data"]["field"] == "bytes");
  CHECK(a.result("session.stats")["digest"] == before["digest"]);
  // At exactly max_vdb_bytes the same file loads.
  o.limits.maxVdbBytes = vdb.size();
  Hub roomy(o);
  TestClient b(roomy);
  b.result("session.create", kCreate);
  CHECK(load(b, vdb, "vdb").contains("result"));
}

#else

TEST_CASE("a server built without OpenVDB refuses format vdb and lists only mzv", "[hub][vdb]") {
  Hub hub(vdbOptions());
  TestClient a(hub);
  const json created = a.result("session.create", kCreate);
  CHECK(created["limits"]["volume_formats"] == json{"mzv"});
  const json before = a.result("session.stats");
  for (const json& r : {a.call("volume.save", {{"format", "vdb"}}), a.call("volume.load", {{"bytes", 4096}, {"format", "vdb"}})}) {
    INFO(r.dump());
    CHECK(r["error"]["code"] == -32602);
    CHECK(r["error"]["data"]["field"] == "format");
    CHECK(r["error"]["message"].get<std::string>().find("built without OpenVDB") != std::string::npos);
  }
  // No upload was expected: the next request is handled as usual.
  const json after = a.result("session.stats");
  CHECK(after["digest"] == before["digest"]);
  CHECK(after["revision"] == before["revision"]);
}

#endif
