// `marzipan batch` end to end: the built binary (test_paths::kCli) run through the shell in a
// scratch directory (test_paths::kCliWorkdir), as a user would run it.
#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include "test_paths.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// A fresh directory per test case, so cases can run in any order or alone.
fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(marzipan::test_paths::kCliWorkdir) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string quote(const fs::path& p) {
  // Appended piece by piece: "'" + string trips GCC 12's false -Wrestrict positive.
  std::string out = p.string();
  out.insert(out.begin(), '\'');
  out.push_back('\'');
  return out;
}

std::string readText(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

void writeText(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

struct Run {
  int status = -1;
  std::string out, err;
};

// Runs `marzipan ARGS` in `dir` and returns its exit status, stdout and stderr.
Run runCli(const fs::path& dir, const std::string& args) {
  const std::string command = "cd " + quote(dir) + " && " + quote(marzipan::test_paths::kCli) + " " + args + " >stdout.txt 2>stderr.txt";
  const int raw = std::system(command.c_str());
  Run r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = readText(dir / "stdout.txt");
  r.err = readText(dir / "stderr.txt");
  return r;
}

std::vector<json> statsLines(const std::string& out) {
  std::vector<json> lines;
  std::istringstream s(out);
  for (std::string line; std::getline(s, line);) lines.push_back(json::parse(line));
  return lines;
}

const char* const kOps = R"(# sculpt a 64^3 sphere (radius 22.4 around 31.5)
{"tool":"add_blob","center":[53.9,31.5,31.5],"radius":8,"strength":1}
{"tool":"remove_blob","center":[31.5,53.9,31.5],"radius":6}

{"tool":"smooth","center":[53.9,31.5,31.5],"radius":10,"strength":0.5}
{"tool":"csg_add","shape":"cylinder","center":[31.5,31.5,31.5],"radius":8,"axis":"z","blend":2}
{"tool":"csg_subtract","shape":"box","center":[31.5,9.1,31.5],"radius":5}
{"op":"morph","kind":"close","radius":1}
{"op":"smooth","global":true,"iterations":1}
)";

std::uint32_t bigEndian32(const std::string& bytes, std::size_t at) {
  return std::uint32_t(std::uint8_t(bytes[at])) << 24 | std::uint32_t(std::uint8_t(bytes[at + 1])) << 16 |
         std::uint32_t(std::uint8_t(bytes[at + 2])) << 8 | std::uint32_t(std::uint8_t(bytes[at + 3]));
}

}  // namespace

TEST_CASE("batch, export STL, import it again: same volume within 2%, stable digests", "[cli]") {
  const fs::path dir = scratch("roundtrip");
  writeText(dir / "ops.jsonl", kOps);
  writeText(dir / "none.jsonl", "");

  const Run sculpt = runCli(dir, "batch ops.jsonl --size 64 --stats --out out.stl");
  INFO(sculpt.err);
  REQUIRE(sculpt.status == 0);
  const std::vector<json> stats = statsLines(sculpt.out);
  REQUIRE(stats.size() == 1);
  const json& s = stats[0];
  CHECK(s["revision"] == 7);
  CHECK(s["components"] == 1);
  CHECK(s["inside_volume"].get<double>() > 30000);
  CHECK(s["surface_area"].get<double>() > 4000);
  // The shape of session.stats's measures (service/measures_json.hpp).
  CHECK(s["bounds"]["empty"] == false);
  CHECK(s["bounds"]["lo"].size() == 3);
  CHECK(s["bounds"]["hi"].size() == 3);
  CHECK(s["gradient_error"]["max"].get<double>() >= s["gradient_error"]["mean"].get<double>());
  CHECK(s["gradient_error"]["voxels"].get<std::size_t>() > 0);
  CHECK(s["digest"].get<std::string>().size() == 16);
  CHECK(s["ms"].get<double>() > 0);
  REQUIRE(fs::file_size(dir / "out.stl") > 84);

  // The same input gives the same digest, for any thread count.
  const Run again = runCli(dir, "batch ops.jsonl --size 64 --stats --threads 1");
  REQUIRE(again.status == 0);
  CHECK(statsLines(again.out).at(0)["digest"] == s["digest"]);

  const Run imported = runCli(dir, "batch none.jsonl --size 64 --load out.stl --stats");
  INFO(imported.err);
  REQUIRE(imported.status == 0);
  const json i = statsLines(imported.out).at(0);
  CHECK(i["revision"] == 0);
  CHECK(i["components"] == 1);
  const double v0 = s["inside_volume"].get<double>(), v1 = i["inside_volume"].get<double>();
  CHECK(std::abs(v1 - v0) <= 0.02 * v0);
  for (int a = 0; a < 3; ++a) {
    CHECK(std::abs(i["bounds"]["lo"][a].get<double>() - s["bounds"]["lo"][a].get<double>()) < 0.5);
    CHECK(std::abs(i["bounds"]["hi"][a].get<double>() - s["bounds"]["hi"][a].get<double>()) < 0.5);
  }
  const Run importedAgain = runCli(dir, "batch none.jsonl --size 64 --load out.stl --stats --threads 2");
  REQUIRE(importedAgain.status == 0);
  CHECK(statsLines(importedAgain.out).at(0)["digest"] == i["digest"]);
}

TEST_CASE("a saved volume loads back bit for bit and keeps its revision", "[cli]") {
  const fs::path dir = scratch("mzv");
  writeText(dir / "ops.jsonl", kOps);
  writeText(dir / "more.jsonl", "{\"op\":\"morph\",\"kind\":\"dilate\",\"radius\":1}\n");
  const Run sculpt = runCli(dir, "batch ops.jsonl --size 64 --stats --out out.mzv");
  REQUIRE(sculpt.status == 0);
  const json s = statsLines(sculpt.out).at(0);

  const Run loaded = runCli(dir, "batch - --load out.mzv --stats < /dev/null");
  INFO(loaded.err);
  REQUIRE(loaded.status == 0);
  const json l = statsLines(loaded.out).at(0);
  CHECK(l["digest"] == s["digest"]);
  CHECK(l["revision"] == 7);
  CHECK(l["inside_volume"] == s["inside_volume"]);

  const Run more = runCli(dir, "batch more.jsonl --load out.mzv --stats");
  REQUIRE(more.status == 0);
  CHECK(statsLines(more.out).at(0)["revision"] == 8);
}

// MARZIPAN_CLI_HAS_OPENVDB: the binary was built with -DMARZIPAN_WITH_OPENVDB=ON.
TEST_CASE(".vdb: a level set written by batch loads back with the same distances, or is refused without OpenVDB", "[cli]") {
  const fs::path dir = scratch("vdb");
  writeText(dir / "ops.jsonl", kOps);
#ifdef MARZIPAN_CLI_HAS_OPENVDB
  const Run sculpt = runCli(dir, "batch ops.jsonl --size 64 --stats --out out.vdb");
  INFO(sculpt.err);
  REQUIRE(sculpt.status == 0);
  const json s = statsLines(sculpt.out).at(0);
  CHECK(readText(dir / "out.vdb").substr(0, 4) == " BDV");  // OpenVDB's magic number, 0x56444220 little-endian

  const Run loaded = runCli(dir, "batch - --load out.vdb --size 64 --stats < /dev/null");
  INFO(loaded.err);
  REQUIRE(loaded.status == 0);
  const json l = statsLines(loaded.out).at(0);
  CHECK(l["revision"] == 0);
  // The band's floats are stored as they are and the rest is +-band on both sides: the same voxels.
  CHECK(l["digest"] == s["digest"]);
  CHECK(l["inside_volume"] == s["inside_volume"]);
  CHECK(l["surface_area"] == s["surface_area"]);

  writeText(dir / "text.vdb", "not a vdb file\n");
  const Run bad = runCli(dir, "batch - --load text.vdb --stats < /dev/null");
  CHECK(bad.status == 1);
  CHECK_THAT(bad.err, Catch::Contains("text.vdb"));
  CHECK(runCli(dir, "batch - --load missing.vdb < /dev/null").status == 1);
  CHECK(runCli(dir, "batch - --load out.vdb --fit 2 < /dev/null").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --out again.vdb --max-triangles 100").status == 2);
  CHECK_FALSE(fs::exists(dir / "again.vdb"));
#else
  const Run out = runCli(dir, "batch ops.jsonl --size 64 --out out.vdb");
  CHECK(out.status == 2);
  CHECK_THAT(out.err, Catch::Contains("MARZIPAN_WITH_OPENVDB"));
  CHECK_FALSE(fs::exists(dir / "out.vdb"));
  writeText(dir / "in.vdb", "");
  const Run in = runCli(dir, "batch ops.jsonl --load in.vdb");
  CHECK(in.status == 2);
  CHECK_THAT(in.err, Catch::Contains("MARZIPAN_WITH_OPENVDB"));
#endif
}

TEST_CASE("stats every K ops (--stats-every) and after the last", "[cli]") {
  const fs::path dir = scratch("every");
  writeText(dir / "ops.jsonl", kOps);
  const Run r = runCli(dir, "batch ops.jsonl --size 64 --stats-every 3");
  REQUIRE(r.status == 0);
  const std::vector<json> lines = statsLines(r.out);
  REQUIRE(lines.size() == 3);
  CHECK(lines[0]["revision"] == 3);
  CHECK(lines[1]["revision"] == 6);
  CHECK(lines[2]["revision"] == 7);
  CHECK(lines[0]["ms"].get<double>() <= lines[2]["ms"].get<double>());
}

TEST_CASE("a bad line stops the run with its line number, exit 1 and no output", "[cli]") {
  const fs::path dir = scratch("bad");
  writeText(dir / "ops.jsonl",
            "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5]}\n"
            "# a comment\n"
            "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5],\"radius\":\"big\"}\n"
            "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5]}\n");
  const Run r = runCli(dir, "batch ops.jsonl --size 64 --stats --out out.stl --render out.png");
  CHECK(r.status == 1);
  CHECK_THAT(r.err, Catch::Contains("ops.jsonl:3:"));
  CHECK_THAT(r.err, Catch::Contains("\"radius\""));
  CHECK(r.out.empty());
  CHECK_FALSE(fs::exists(dir / "out.stl"));
  CHECK_FALSE(fs::exists(dir / "out.png"));

  writeText(dir / "json.jsonl", "{\"op\":\"morph\",\"kind\":\"open\",\"radius\":1}\n\n{\"op\":\n");
  const Run broken = runCli(dir, "batch json.jsonl --size 64 --out out.mzv");
  CHECK(broken.status == 1);
  CHECK_THAT(broken.err, Catch::Contains("json.jsonl:3: not valid JSON"));
  CHECK_FALSE(fs::exists(dir / "out.mzv"));

  // An op the engine refuses (its region misses the domain) is reported the same way.
  writeText(dir / "engine.jsonl",
            "{\"op\":\"morph\",\"kind\":\"dilate\",\"radius\":1}\n"
            "\n"
            "{\"tool\":\"add_blob\",\"center\":[500,500,500]}\n");
  const Run refused = runCli(dir, "batch engine.jsonl --size 64 --out out.obj --stats");
  CHECK(refused.status == 1);
  CHECK_THAT(refused.err, Catch::Contains("engine.jsonl:3: center:"));
  CHECK(refused.out.empty());
  CHECK_FALSE(fs::exists(dir / "out.obj"));
}

TEST_CASE("the surface tools in an ops file each change the volume, and a flatten over nothing stops the run", "[cli]") {
  const fs::path dir = scratch("surface");
  // On the 64^3 sphere's side (radius 22.4 around 31.5); flatten and contrast fit their plane
  // at their centre.
  writeText(dir / "ops.jsonl",
            "{\"tool\":\"inflate\",\"center\":[53.9,31.5,31.5],\"radius\":6}\n"
            "{\"tool\":\"clay\",\"center\":[53.9,36,31.5],\"radius\":6}\n"
            "{\"tool\":\"flatten\",\"center\":[53.9,31.5,31.5],\"radius\":8}\n"
            "{\"tool\":\"contrast\",\"center\":[31.5,53.9,31.5],\"radius\":8}\n"
            "{\"tool\":\"crease\",\"center\":[31.5,31.5,53.9],\"radius\":6,\"strength\":0.5}\n");
  const Run r = runCli(dir, "batch ops.jsonl --size 64 --stats-every 1");
  REQUIRE(r.status == 0);
  const std::vector<json> lines = statsLines(r.out);
  REQUIRE(lines.size() == 5);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    INFO("line " << i + 1);
    CHECK(lines[i]["revision"] == i + 1);
    if (i > 0) CHECK(lines[i]["digest"] != lines[i - 1]["digest"]);
  }
  writeText(dir / "nothing.jsonl",
            "{\"tool\":\"crease\",\"center\":[31.5,31.5,53.9]}\n"
            "{\"tool\":\"flatten\",\"center\":[4,4,4],\"radius\":3}\n");
  const Run refused = runCli(dir, "batch nothing.jsonl --size 64 --out out.mzv");
  CHECK(refused.status == 1);
  CHECK_THAT(refused.err, Catch::Contains("nothing.jsonl:2: center: no surface lies within the radius"));
  CHECK_FALSE(fs::exists(dir / "out.mzv"));
}

TEST_CASE("warp strokes in an ops file: a line is a stroke from its anchor, only a grab's last point counts", "[cli]") {
  const fs::path dir = scratch("warp");
  // The 64^3 sphere's surface point on +x is (53.9, 31.5, 31.5).
  writeText(dir / "path.jsonl",
            "{\"stroke\":{\"tool\":\"grab\",\"radius\":12},\"dabs\":[[53.9,31.5,31.5],[55,32,31.5],[57,33,31],[59.9,31.5,31.5]]}\n"
            "{\"stroke\":{\"tool\":\"twist\",\"radius\":10,\"direction\":[0,0,1]},\"dabs\":[[31.5,53.9,31.5],[31.5,54,38]]}\n"
            "{\"stroke\":{\"tool\":\"snake_hook\",\"radius\":6},\"dabs\":[{\"ray\":{\"origin\":[31.5,31.5,70],\"direction\":[0,0,-1]}},"
            "[31.5,31.5,56],[31.5,33,58],[31.5,35,60]]}\n"
            "{\"stroke\":{\"tool\":\"pinch_path\",\"radius\":6,\"strength\":0.8},\"dabs\":[[31.5,9.1,31.5],"
            "{\"center\":[33.7,9.2,31.5],\"pressure\":0.5},[35.9,9.6,31.5]]}\n");
  writeText(dir / "last.jsonl", "{\"stroke\":{\"tool\":\"grab\",\"radius\":12},\"dabs\":[[53.9,31.5,31.5],[59.9,31.5,31.5]]}\n");
  const Run r = runCli(dir, "batch path.jsonl --size 64 --stats-every 1");
  REQUIRE(r.status == 0);
  const Run last = runCli(dir, "batch last.jsonl --size 64 --stats");
  REQUIRE(last.status == 0);
  const std::vector<json> lines = statsLines(r.out);
  REQUIRE(lines.size() == 4);
  CHECK(lines[0]["digest"] == statsLines(last.out)[0]["digest"]);
  // The anchor went 6 vu out along +x, to 59.9 (within 0.25 vu; bounds are whole voxels).
  CHECK(lines[0]["bounds"]["hi"][0].get<double>() == Approx(59.9).margin(1.25));
  CHECK(lines[1]["digest"] != lines[0]["digest"]);
  CHECK(lines[2]["digest"] != lines[1]["digest"]);
  CHECK(lines[2]["bounds"]["hi"][2].get<double>() > 58);
  // A pinch path's line is its path on the surface, with pressures.
  CHECK(lines[3]["digest"] != lines[2]["digest"]);

  writeText(dir / "bad.jsonl",
            "{\"stroke\":{\"tool\":\"grab\"},\"dabs\":[[53.9,31.5,31.5],[55,31.5,31.5]]}\n"
            "{\"stroke\":{\"tool\":\"grab\"},\"dabs\":[[58,31.5,31.5],[60,31.5,31.5]]}\n");
  const Run off = runCli(dir, "batch bad.jsonl --size 64 --out out.mzv");
  CHECK(off.status == 1);
  CHECK_THAT(off.err, Catch::Contains("bad.jsonl:2: center: the anchor (the stroke's first dab) must lie on the surface"));
  CHECK_FALSE(fs::exists(dir / "out.mzv"));
  writeText(dir / "brush.jsonl", "{\"stroke\":{\"tool\":\"add_blob\"},\"dabs\":[[53.9,31.5,31.5]]}\n");
  const Run brush = runCli(dir, "batch brush.jsonl --size 64");
  CHECK(brush.status == 1);
  CHECK_THAT(brush.err, Catch::Contains("brush.jsonl:1: a stroke line is for the warp tools"));
  writeText(dir / "mirror.jsonl", "{\"stroke\":{\"tool\":\"grab\",\"symmetry\":[\"x\"]},\"dabs\":[[53.9,31.5,31.5]]}\n");
  const Run mirror = runCli(dir, "batch mirror.jsonl --size 64");
  CHECK(mirror.status == 1);
  CHECK_THAT(mirror.err, Catch::Contains("mirror.jsonl:1:"));
  CHECK_THAT(mirror.err, Catch::Contains("symmetry"));
}

TEST_CASE("paint and mask in an ops file: stroke lines colour, the mask op lines hold the clay", "[cli][paint]") {
  const fs::path dir = scratch("paint");
  // The 64^3 sphere's surface points on +x and -x; the paint mirrored across x reaches both.
  writeText(dir / "paint.jsonl",
            "{\"stroke\":{\"tool\":\"paint\",\"color\":[200,20,10],\"radius\":6,\"symmetry\":[\"x\"]},"
            "\"dabs\":[[53.9,31.5,31.5],{\"center\":[53.9,34,31.5],\"pressure\":0.5}]}\n"
            "{\"op\":\"mask\",\"action\":\"fill\"}\n"
            "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5],\"radius\":8}\n"
            "{\"op\":\"mask\",\"action\":\"invert\"}\n"
            "{\"stroke\":{\"tool\":\"mask\",\"radius\":8,\"erase\":true},\"dabs\":[[9.1,31.5,31.5]]}\n"
            "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5],\"radius\":8}\n");
  const Run r = runCli(dir, "batch paint.jsonl --size 64 --stats-every 1 --out painted.mzv");
  INFO(r.err);
  REQUIRE(r.status == 0);
  const std::vector<json> lines = statsLines(r.out);
  REQUIRE(lines.size() == 6);
  const Run plain = runCli(dir, "batch /dev/null --size 64 --stats");
  REQUIRE(plain.status == 0);
  const json start = statsLines(plain.out)[0];
  // Paint moves no geometry: the same volume and area, another digest.
  CHECK(lines[0]["digest"] != start["digest"]);
  CHECK(lines[0]["inside_volume"] == start["inside_volume"]);
  CHECK(lines[0]["surface_area"] == start["surface_area"]);
  // Under the full mask the add_blob changes nothing.
  CHECK(lines[1]["digest"] != lines[0]["digest"]);
  CHECK(lines[2]["digest"] == lines[1]["digest"]);
  // Inverted, the mask is gone (the paint stays): the blob grows the solid.
  CHECK(lines[3]["digest"] == lines[0]["digest"]);
  CHECK(lines[4]["digest"] == lines[3]["digest"]);  // erasing where nothing is masked: no change
  CHECK(lines[5]["inside_volume"].get<double>() > lines[4]["inside_volume"].get<double>());
  // A painted volume is written as .mzv version 2.
  const std::string mzv = readText(dir / "painted.mzv");
  REQUIRE(mzv.size() > 8);
  CHECK(mzv.substr(0, 4) == "MZVF");
  CHECK(std::uint8_t(mzv[4]) == 2);

  writeText(dir / "bad.jsonl", "{\"op\":\"mask\",\"action\":\"fill\"}\n{\"op\":\"mask\",\"action\":\"blur\"}\n");
  const Run bad = runCli(dir, "batch bad.jsonl --size 64");
  CHECK(bad.status == 1);
  CHECK_THAT(bad.err, Catch::Contains("bad.jsonl:2:"));
  CHECK_THAT(bad.err, Catch::Contains("action"));
  writeText(dir / "csg.jsonl", "{\"tool\":\"csg_add\",\"shape\":\"sphere\",\"center\":[57.9,31.5,31.5],\"radius\":4,"
                               "\"color\":[20,40,220]}\n");
  writeText(dir / "csg-plain.jsonl", "{\"tool\":\"csg_add\",\"shape\":\"sphere\",\"center\":[57.9,31.5,31.5],\"radius\":4}\n");
  const Run coloured = runCli(dir, "batch csg.jsonl --size 64 --stats");
  const Run uncoloured = runCli(dir, "batch csg-plain.jsonl --size 64 --stats");
  REQUIRE(coloured.status == 0);
  REQUIRE(uncoloured.status == 0);
  // The same union, the colour only in the digest.
  CHECK(statsLines(coloured.out)[0]["inside_volume"] == statsLines(uncoloured.out)[0]["inside_volume"]);
  CHECK(statsLines(coloured.out)[0]["digest"] != statsLines(uncoloured.out)[0]["digest"]);
  writeText(dir / "nocolour.jsonl", "{\"stroke\":{\"tool\":\"paint\"},\"dabs\":[[53.9,31.5,31.5]]}\n");
  const Run nocolour = runCli(dir, "batch nocolour.jsonl --size 64");
  CHECK(nocolour.status == 1);
  CHECK_THAT(nocolour.err, Catch::Contains("nocolour.jsonl:1:"));
  CHECK_THAT(nocolour.err, Catch::Contains("color"));
}

TEST_CASE("rendering (--render) writes a PNG or JPEG of the requested size", "[cli]") {
  const fs::path dir = scratch("render");
  writeText(dir / "ops.jsonl", "{\"tool\":\"add_blob\",\"center\":[53.9,31.5,31.5]}\n");
  const Run r = runCli(dir, "batch ops.jsonl --size 64 --solid pig --render frame.png --width 160 --height 90");
  INFO(r.err);
  REQUIRE(r.status == 0);
  const std::string png = readText(dir / "frame.png");
  REQUIRE(png.size() > 33);
  CHECK(png.substr(0, 8) == std::string("\x89PNG\r\n\x1a\n", 8));
  CHECK(png.substr(12, 4) == "IHDR");
  CHECK(bigEndian32(png, 16) == 160);
  CHECK(bigEndian32(png, 20) == 90);

  const Run jpeg = runCli(dir,
                            "batch ops.jsonl --size 64 --render frame.jpg --camera-eye 150,80,120 "
                            "--camera-target 31.5,31.5,31.5 --camera-up 0,1,0 --fov 30 --width 64 --height 48 "
                            "--shading normals --quality 75");
  INFO(jpeg.err);
  REQUIRE(jpeg.status == 0);
  const std::string jpg = readText(dir / "frame.jpg");
  REQUIRE(jpg.size() > 4);
  CHECK(std::uint8_t(jpg[0]) == 0xFF);
  CHECK(std::uint8_t(jpg[1]) == 0xD8);
}

TEST_CASE("usage errors exit with 2, help with 0", "[cli]") {
  const fs::path dir = scratch("usage");
  writeText(dir / "ops.jsonl", "");
  CHECK(runCli(dir, "").status == 2);
  CHECK(runCli(dir, "frobnicate").status == 2);
  CHECK(runCli(dir, "batch").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --size 4").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --solid cube").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --out out.xyz").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --render out.gif").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --render out.png --camera-eye 1,2").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --render out.png --camera-eye 31.5,31.5,31.5 --size 64").status == 2);
  CHECK(runCli(dir, "batch ops.jsonl --unknown").status == 2);
  CHECK(runCli(dir, "batch missing.jsonl").status == 1);
  CHECK_FALSE(fs::exists(dir / "out.png"));

  const Run help = runCli(dir, "--help");
  CHECK(help.status == 0);
  CHECK_THAT(help.out, Catch::Contains("batch"));
  const Run batchHelp = runCli(dir, "batch --help");
  CHECK(batchHelp.status == 0);
  CHECK_THAT(batchHelp.out, Catch::Contains("--stats-every"));
  CHECK_THAT(batchHelp.out, Catch::Contains("csg_intersect"));
}
