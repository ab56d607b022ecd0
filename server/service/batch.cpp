// `marzipan batch` (see batch.hpp). The order of work is chosen so that a mistake costs as
// little as possible: arguments, then every ops line (parsed before any is applied), then the
// starting solid, then the operations, and only then the output files.
#include "service/batch.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/decimate.hpp"
#include "engine/errors.hpp"
#include "engine/image_io.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/measures.hpp"
#include "engine/mesh_io.hpp"
#include "engine/raycast.hpp"
#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume_file.hpp"
#ifdef MARZIPAN_HAS_OPENVDB
#include "engine/openvdb/vdb_io.hpp"
#endif
#include "protocol/cpp/json_checks.hpp"
#include "protocol/cpp/ops.hpp"
#include "protocol/cpp/rpc.hpp"
#include "service/apply_op.hpp"
#include "service/session.hpp"
#include "service/measures_json.hpp"

namespace marzipan::service {
namespace {

constexpr int kDefaultSize = 128;
constexpr int kDefaultQuality = 90;

// Thrown for anything wrong with the command line itself (exit status 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// Thrown for bad input: the message is complete, with its "FILE:LINE:" or "FILE:" prefix.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// .vdb files (OpenVDB level sets) are read and written only by a build with OpenVDB.
#ifdef MARZIPAN_HAS_OPENVDB
constexpr bool kWithOpenVdb = true;
#else
constexpr bool kWithOpenVdb = false;
#endif
void requireOpenVdb(const std::string& option, const std::string& path) {
  if (!kWithOpenVdb)
    throw UsageError(option + " \"" + path +
                     "\": this marzipan was built without OpenVDB (cmake -DMARZIPAN_WITH_OPENVDB=ON reads and writes .vdb)");
}

// "a, b or c" from a wire-name table, for messages that list what is accepted.
template <class E, std::size_t N>
std::string nameList(const std::array<WireName<E>, N>& names) {
  std::string out;
  for (std::size_t i = 0; i < N; ++i) out += (i == 0 ? "" : i + 1 == N ? " or " : ", ") + std::string(names[i].name);
  return out;
}

// A warp stroke, one line: {"stroke": {stroke.begin's params}, "dabs": [[x,y,z] | {center |
// ray}, ...]}, the first dab the anchor (PROTOCOL.md, warp strokes), applied as one message.
struct WarpLine {
  WarpStroke settings;
  std::vector<protocol::DabParam> dabs;
};

// A paint or mask stroke, one line: {"stroke": {stroke.begin's params}, "dabs": [[x,y,z] | {center
// | ray, pressure?}, ...]}, applied as one message of a stroke (symmetry as in stroke.begin; rays
// picked on the volume as the line began).
struct PaintLine {
  PaintSettings settings;
  Symmetry symmetry;
  std::vector<protocol::DabParam> dabs;
};

struct NumberedOp {
  int line;
  std::variant<protocol::Op, WarpLine, PaintLine> op;
};

// Dabs in one line: far more than a drag has, few enough to parse at once.
constexpr std::size_t kMaxLineDabs = 1 << 16;

std::variant<WarpLine, PaintLine> parseStrokeLine(const nlohmann::json& obj) {
  using protocol::OpError;
  for (const auto& item : obj.items())
    if (item.key() != "stroke" && item.key() != "dabs")
      throw OpError(item.key(), "a stroke line has \"stroke\" and \"dabs\" only, got \"" + item.key() + "\"");
  const protocol::StrokeBeginParams begin = protocol::parseStrokeBeginParams(obj.at("stroke"));
  if (!begin.warp && !begin.paint)
    throw OpError("stroke", "a stroke line is for the warp tools (grab, snake_hook, ...) and paint and mask: a brush's "
                            "dabs are op lines");
  const auto dabs = obj.find("dabs");
  if (dabs == obj.end())
    throw OpError("dabs", begin.warp ? "\"dabs\" is missing: the anchor, then the pointer's points"
                                     : "\"dabs\" is missing: the centres the brush is swept over");
  nlohmann::json message{{"stroke", 1}, {"dabs", nlohmann::json::array()}};
  if (dabs->is_array())
    for (const nlohmann::json& d : *dabs) message["dabs"].push_back(d.is_array() ? nlohmann::json{{"center", d}} : d);
  else
    message["dabs"] = *dabs;
  if (begin.paint) {
    PaintLine line;
    line.settings = paintSettingsOf(begin);
    line.symmetry = Symmetry{begin.mirrorX, begin.mirrorY, begin.mirrorZ};
    line.dabs = protocol::parseStrokeDabsParams(message, kMaxLineDabs).dabs;
    return line;
  }
  WarpLine line;
  line.settings.tool = begin.warp->tool;
  line.settings.radius = begin.radius;
  line.settings.strength = begin.strength;
  line.settings.volume = begin.warp->volume;
  line.settings.direction = begin.warp->direction;
  line.dabs = protocol::parseStrokeDabsParams(message, kMaxLineDabs).dabs;
  for (std::size_t i = 1; i < line.dabs.size(); ++i)
    if (!std::holds_alternative<Vec3>(line.dabs[i].at))
      throw OpError("dabs", "\"dabs\"[" + std::to_string(i) + "]: after the anchor a warp's dabs are the pointer's points");
  return line;
}

// A paint stroke line on vol: its dabs (rays picked on vol as it is) and their mirror images,
// one application of paintStroke without memory.
Edit applyPaintLine(Volume& vol, const PaintLine& line, ThreadPool& pool) {
  std::vector<StrokeDab> images;
  for (const protocol::DabParam& d : line.dabs) {
    Vec3 centre;
    if (const auto* c = std::get_if<Vec3>(&d.at)) {
      centre = *c;
    } else {
      const auto& ray = std::get<protocol::RayParam>(d.at);
      const std::optional<Vec3> hit = pickSurface(vol, ray.origin, ray.direction);
      if (!hit) continue;  // a ray that misses paints nothing, as in a session's stroke
      centre = *hit;
    }
    for (const StrokeDab& image : mirrorImages(StrokeDab{centre, d.pressure, Vec3{}}, line.symmetry, vol.dims()))
      images.push_back(image);
  }
  return paintStroke(vol, line.settings, images, {}, pool);
}

// A warp stroke line on vol: the volume as the line began is its base.
Edit applyWarpLine(Volume& vol, WarpLine line, ThreadPool& pool) {
  const Volume base = vol;
  Vec3 anchor;
  if (const auto* c = std::get_if<Vec3>(&line.dabs[0].at)) {
    anchor = *c;
  } else {
    const auto& ray = std::get<protocol::RayParam>(line.dabs[0].at);
    const std::optional<Vec3> hit = pickSurface(base, ray.origin, ray.direction);
    if (!hit) throw EngineError(ErrorKind::InvalidArgument, "dabs", "the anchor's ray misses the surface");
    anchor = *hit;
  }
  setWarpAnchor(line.settings, base, anchor);
  std::vector<Vec3> points;
  for (std::size_t i = 1; i < line.dabs.size(); ++i) points.push_back(std::get<Vec3>(line.dabs[i].at));
  return applyWarpStroke(vol, base, line.settings, points, pool);
}

struct Options {
  std::string opsPath;
  std::optional<int> size;
  std::optional<SolidKind> solid;
  std::string load;
  std::optional<double> fitMargin;
  std::string out;
  std::string render;
  std::optional<Vec3> eye, target;
  Vec3 up{0, 1, 0};
  double fov = 40;
  int width = 512, height = 512;
  Shading shading = Shading::Lit;
  std::optional<int> quality;
  DecimateOptions decimate;
  bool stats = false;
  int statsEvery = 0;
  int threads = 0;
};

std::string lowerExtension(const std::string& path) {
  const auto slash = path.find_last_of("/\\");
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

int parseInt(const std::string& option, const std::string& text, int lo, int hi) {
  int v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v < lo || v > hi)
    throw UsageError(option + " takes an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                     ", got \"" + text + "\"");
  return v;
}

double parseDouble(const std::string& option, std::string_view text) {
  double v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v))
    throw UsageError(option + " takes a finite number, got \"" + std::string(text) + "\"");
  return v;
}

Vec3 parseVec3(const std::string& option, const std::string& text) {
  Vec3 v;
  std::string_view rest = text;
  for (int a = 0; a < 3; ++a) {
    const auto comma = rest.find(',');
    if ((a < 2) != (comma != std::string_view::npos))
      throw UsageError(option + " takes three numbers x,y,z, got \"" + text + "\"");
    v[a] = parseDouble(option, rest.substr(0, comma));
    rest = a < 2 ? rest.substr(comma + 1) : std::string_view();
  }
  return v;
}

Options parseOptions(const std::vector<std::string>& args) {
  Options o;
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string name = args[i];
    std::optional<std::string> inlineValue;
    if (name.starts_with("--")) {
      if (const auto eq = name.find('='); eq != std::string::npos) {
        inlineValue = name.substr(eq + 1);
        name.resize(eq);
      }
    } else if (name != "-" && name.starts_with("-")) {
      throw UsageError("unknown option " + name);
    }
    if (!name.starts_with("--")) {
      if (!o.opsPath.empty()) throw UsageError("one OPS file only, got \"" + o.opsPath + "\" and \"" + name + "\"");
      o.opsPath = name;
      continue;
    }
    const auto value = [&]() -> std::string {
      if (inlineValue) return *inlineValue;
      if (i + 1 >= args.size()) throw UsageError(name + " needs a value");
      return args[++i];
    };
    const auto flag = [&] {
      if (inlineValue) throw UsageError(name + " takes no value");
    };
    if (name == "--size") {
      o.size = parseInt(name, value(), 8, kMaxDomainSide);
    } else if (name == "--solid") {
      const std::string v = value();
      o.solid = solidKindFromName(v);
      if (!o.solid)
        throw UsageError("--solid takes sphere, box, torus, cylinder, dumbbell, pig or empty, got \"" + v + "\"");
    } else if (name == "--load") {
      o.load = value();
    } else if (name == "--fit") {
      o.fitMargin = parseDouble(name, value());
      if (*o.fitMargin < 0) throw UsageError("--fit takes a margin of 0 vu or more");
    } else if (name == "--out") {
      o.out = value();
    } else if (name == "--max-triangles") {
      o.decimate.maxTriangles = std::size_t(parseInt(name, value(), 1, std::numeric_limits<int>::max()));
    } else if (name == "--max-error") {
      o.decimate.maxError = parseDouble(name, value());
      if (!(*o.decimate.maxError > 0)) throw UsageError("--max-error takes a number of vu above 0");
    } else if (name == "--render") {
      o.render = value();
    } else if (name == "--camera-eye") {
      o.eye = parseVec3(name, value());
    } else if (name == "--camera-target") {
      o.target = parseVec3(name, value());
    } else if (name == "--camera-up") {
      o.up = parseVec3(name, value());
    } else if (name == "--fov") {
      o.fov = parseDouble(name, value());
    } else if (name == "--width") {
      o.width = parseInt(name, value(), 1, kMaxFrameSide);
    } else if (name == "--height") {
      o.height = parseInt(name, value(), 1, kMaxFrameSide);
    } else if (name == "--shading") {
      const std::string v = value();
      if (const auto s = shadingFromName(v)) o.shading = *s;
      else throw UsageError("--shading takes " + nameList(kShadingNames) + ", got \"" + v + "\"");
    } else if (name == "--quality") {
      o.quality = parseInt(name, value(), 1, 100);
    } else if (name == "--stats") {
      flag();
      o.stats = true;
    } else if (name == "--stats-every") {
      o.statsEvery = parseInt(name, value(), 1, 1 << 30);
      o.stats = true;
    } else if (name == "--threads") {
      o.threads = parseInt(name, value(), 0, 1024);
    } else {
      throw UsageError("unknown option " + name);
    }
  }

  if (o.opsPath.empty()) throw UsageError("missing the OPS file (a path, or - for standard input)");
  const std::string loadExt = lowerExtension(o.load);
  if (!o.load.empty()) {
    if (loadExt != "mzv" && loadExt != "vdb" && !meshFormatFromName(loadExt))
      throw UsageError("--load takes a .mzv, .vdb, .stl, .obj, .ply or .glb file, got \"" + o.load + "\"");
    if (loadExt == "vdb") requireOpenVdb("--load", o.load);
    if (o.solid) throw UsageError("--solid and --load exclude each other");
    if (loadExt == "mzv" && o.size) throw UsageError("--size does not apply to a .mzv file, which has its own size");
    if ((loadExt == "mzv" || loadExt == "vdb") && o.fitMargin) throw UsageError("--fit applies to meshes only");
  } else if (o.fitMargin) {
    throw UsageError("--fit applies to a mesh given with --load");
  }
  if (!o.out.empty()) {
    const std::string ext = lowerExtension(o.out);
    if (ext != "mzv" && ext != "vdb" && !meshFormatFromName(ext))
      throw UsageError("--out takes a .stl, .obj, .ply, .glb, .mzv or .vdb file, got \"" + o.out + "\"");
    if (ext == "vdb") requireOpenVdb("--out", o.out);
  }
  if ((o.decimate.maxTriangles || o.decimate.maxError) &&
      (o.out.empty() || lowerExtension(o.out) == "mzv" || lowerExtension(o.out) == "vdb"))
    throw UsageError("--max-triangles and --max-error apply to a mesh written with --out");
  if (!o.render.empty()) {
    const std::string ext = lowerExtension(o.render);
    if (ext != "png" && ext != "jpg" && ext != "jpeg")
      throw UsageError("--render takes a .png or .jpg file, got \"" + o.render + "\"");
    if (ext == "png" && o.quality) throw UsageError("--quality applies to JPEG images only");
  } else if (o.eye || o.target || o.quality) {
    throw UsageError("camera and image options need --render FILE");
  }
  return o;
}

// Lines are trimmed of surrounding white space (and a CR), so files from any editor work.
std::vector<NumberedOp> readOps(const std::string& path, std::istream& in) {
  std::vector<NumberedOp> ops;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto last = line.find_last_not_of(" \t\r");
    try {
      const nlohmann::json obj = protocol::checks::parseJsonText(std::string_view(line).substr(first, last + 1 - first));
      if (obj.is_object() && obj.contains("stroke")) {
        std::variant<WarpLine, PaintLine> stroke = parseStrokeLine(obj);
        if (auto* w = std::get_if<WarpLine>(&stroke)) ops.push_back({number, std::move(*w)});
        else ops.push_back({number, std::get<PaintLine>(std::move(stroke))});
      } else {
        ops.push_back({number, protocol::parseOp(obj)});
      }
    } catch (const protocol::OpError& e) {
      throw InputError(path + ":" + std::to_string(number) + ": " + e.what());
    } catch (const protocol::RpcException& e) {  // a stroke line of more than kMaxLineDabs dabs
      throw InputError(path + ":" + std::to_string(number) + ": " + e.what());
    }
  }
  if (in.bad()) throw InputError(path + ": cannot be read");
  return ops;
}

std::vector<NumberedOp> readOpsFile(const std::string& path) {
  if (path == "-") return readOps("<stdin>", std::cin);
  std::ifstream f(path);
  if (!f) throw InputError(path + ": cannot be opened");
  return readOps(path, f);
}

std::vector<std::uint8_t> readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path + ": cannot be opened");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw InputError(path + ": cannot be read");
  return bytes;
}

Volume startingVolume(const Options& o, ThreadPool& pool) {
  const int n = o.size.value_or(kDefaultSize);
  const Int3 dims{n, n, n};
  if (o.load.empty()) return makeSolid(o.solid.value_or(SolidKind::Sphere), dims, Volume::kDefaultBand, pool);
  try {
    const std::string ext = lowerExtension(o.load);
    if (ext == "mzv") return loadVolumeFile(o.load);
#ifdef MARZIPAN_HAS_OPENVDB
    if (ext == "vdb") return loadVdb(o.load, dims);
#endif
    Mesh mesh = parseMesh(readBytes(o.load), *meshFormatFromName(ext));
    if (o.fitMargin) mesh = fitMeshToDomain(mesh, dims, *o.fitMargin);
    return importMesh(mesh, dims, Volume::kDefaultBand, pool);
  } catch (const EngineError& e) {
    throw InputError(o.load + ": " + e.what());
  }
}

// A 3/4 view from the front right and above (the pig faces +x, y is up) that fits the
// sphere inscribed in the domain into the vertical field of view: the starting solids fill
// it, whereas fitting the whole cube, corners included, leaves them small.
Camera makeCamera(const Options& o, Int3 dims) {
  Camera c;
  const Vec3 centre{(dims.x - 1) / 2.0, (dims.y - 1) / 2.0, (dims.z - 1) / 2.0};
  c.target = o.target.value_or(centre);
  c.fovY_degrees = o.fov;
  c.up = o.up;
  c.width = o.width;
  c.height = o.height;
  if (o.eye) {
    c.eye = *o.eye;
  } else {
    const double radius = 0.5 * std::max({dims.x, dims.y, dims.z});
    const double halfFov = std::clamp(o.fov, 1.0, 170.0) * 0.5 * std::numbers::pi / 180.0;
    c.eye = c.target + normalized(Vec3{0.55, 0.42, 0.72}) * (radius / std::sin(halfFov));
  }
  try {
    c.validate();
  } catch (const EngineError& e) {
    throw UsageError(std::string("camera: ") + e.what());
  }
  return c;
}

// revision, the measures as session.stats gives them (measures_json.hpp), ms.
nlohmann::ordered_json statsLine(const Volume& vol, double ms) {
  nlohmann::ordered_json line = {{"revision", vol.revision()}};
  putMeasures(line, measure(vol));
  line["ms"] = std::round(ms * 1000) / 1000;
  return line;
}

void writeOutputs(const Options& o, const Volume& vol, const std::optional<Camera>& camera, ThreadPool& pool,
                  std::ostream& out) {
  if (!o.out.empty()) {
    try {
      const std::string ext = lowerExtension(o.out);
      if (ext == "mzv") {
        saveVolumeFile(vol, o.out);
#ifdef MARZIPAN_HAS_OPENVDB
      } else if (ext == "vdb") {
        saveVdb(vol, o.out);
#endif
      } else {
        Mesh mesh = extractMesh(vol, pool);
        if (o.decimate.maxTriangles || o.decimate.maxError) {
          DecimateResult d = decimateMesh(mesh, vol, o.decimate, pool);
          out << nlohmann::ordered_json{{"mesh", o.out}, {"source_triangles", d.sourceTriangles},
                              {"triangles", d.mesh.triangleCount()}, {"vertices", d.mesh.vertexCount()},
                              {"max_error", d.maxError}}.dump()
              << '\n' << std::flush;
          mesh = std::move(d.mesh);
        }
        writeFile(o.out, exportMesh(mesh, *meshFormatFromName(ext)));
      }
    } catch (const EngineError& e) {
      throw InputError(o.out + ": " + e.what());
    }
  }
  if (camera) {
    try {
      const Frame frame = render(vol, *camera, o.shading, pool, FrameQuality::Still);
      const ImageFormat format = lowerExtension(o.render) == "png" ? ImageFormat::Png : ImageFormat::Jpeg;
      writeFile(o.render,
                encodeImage(frame.rgb, frame.width, frame.height, format, o.quality.value_or(kDefaultQuality)));
    } catch (const EngineError& e) {
      throw InputError(o.render + ": " + e.what());
    }
  }
}

int run(const std::vector<std::string>& args, std::ostream& out) {
  const Options o = parseOptions(args);
  const std::vector<NumberedOp> ops = readOpsFile(o.opsPath);
  ThreadPool pool(o.threads);
  Volume vol = startingVolume(o, pool);
  std::optional<Camera> camera;
  if (!o.render.empty()) camera = makeCamera(o, vol.dims());

  double ms = 0;
  std::size_t applied = 0;
  bool reported = false;
  for (const NumberedOp& item : ops) {
    const auto start = std::chrono::steady_clock::now();
    try {
      if (const auto* op = std::get_if<protocol::Op>(&item.op)) service::applyOp(vol, *op, pool);
      else if (const auto* w = std::get_if<WarpLine>(&item.op)) applyWarpLine(vol, *w, pool);
      else applyPaintLine(vol, std::get<PaintLine>(item.op), pool);
    } catch (const EngineError& e) {
      const std::string path = o.opsPath == "-" ? "<stdin>" : o.opsPath;
      throw InputError(path + ":" + std::to_string(item.line) + ": " + e.what());
    }
    ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    vol.setRevision(vol.revision() + 1);
    ++applied;
    reported = false;
    if (o.statsEvery > 0 && applied % std::size_t(o.statsEvery) == 0) {
      out << statsLine(vol, ms).dump() << '\n' << std::flush;
      reported = true;
    }
  }
  if (o.stats && !reported) out << statsLine(vol, ms).dump() << '\n' << std::flush;
  writeOutputs(o, vol, camera, pool, out);
  return kExitOk;
}

}  // namespace

namespace {

// "a"|"b"|"c": the quoted names of a table, as the usage shows alternatives.
template <class E, std::size_t N>
std::string alternatives(const std::array<WireName<E>, N>& table) {
  std::string out;
  for (const auto& entry : table) out += (out.empty() ? "\"" : "|\"") + std::string(entry.name) + "\"";
  return out;
}

}  // namespace

void printBatchUsage(std::ostream& os) {
  os << R"(Usage: marzipan batch OPS.jsonl [options]

Applies the operation objects in OPS.jsonl, one JSON object per line, to a solid and writes
the result. Blank lines and lines starting with # are skipped; OPS "-" reads standard input.
Every line is checked before the first is applied; output files are written only when every
operation succeeded.

Operations (coordinates and lengths in vu, the voxel spacing; the tools are the tool registry's,
protocol/registry/tools.json, described in protocol/PROTOCOL.md):
  {"tool":)" << alternatives(protocol::kBrushToolNames) << R"(,
   "center":[x,y,z],"radius":8,"strength":1}
  {"op":"smooth","global":true,"iterations":N,"strength":1}   (or "tool":"smooth","global":true)
  {"tool":)" << alternatives(protocol::kCsgToolNames) << R"(,"shape":)" << alternatives(kToolShapeNames) << R"(,
   "center":[x,y,z],"radius":R,"blend":0,"axis":"y"}
  {"op":"morph","kind":)" << alternatives(protocol::kMorphKindNames) << R"(,"radius":K}
  {"stroke":{"tool":)" << alternatives(protocol::kWarpToolNames) << R"(,"radius":8,
   "strength":1,"volume":0.5,"direction":[x,y,z]},"dabs":[[x,y,z],...]}
                        a warp stroke: the first dab the anchor on the surface (or {"ray":
                        {"origin","direction"}}), the others the pointer's points; the volume as
                        the line began is warped (PROTOCOL.md, warp strokes)

Starting solid:
  --size N              domain of N^3 voxels, 8..1024 (default 128)
  --solid NAME          sphere|box|torus|cylinder|dumbbell|pig|empty (default sphere)
  --load FILE           a volume file (.mzv, keeps its own size), an OpenVDB level set
                        (.vdb: voxel x,y,z of the N^3 domain reads the grid's x,y,z) or a
                        closed mesh (.stl, .obj, .ply, .glb) in vu, placed as it is in an N^3
                        domain (vertex colours of .obj, .ply and .glb become the clay's)
  --fit MARGIN          with a mesh: scale and centre it, MARGIN vu from the tightest sides

Output:
  --out FILE            .stl, .obj, .ply or .glb (glTF 2.0) mesh of the surface, .mzv
                        volume file or .vdb OpenVDB level set (.vdb: builds with OpenVDB)
  --max-triangles N     decimate the mesh to at most N triangles (meshoptimizer)
  --max-error E         decimate while meshoptimizer's error estimate stays within E vu;
                        with either, one JSON line on stdout: mesh, source_triangles,
                        triangles, vertices, max_error (measured distance to the surface, vu)
  --render FILE         .png or .jpg ray-cast image of the result
  --camera-eye X,Y,Z    default: a 3/4 view from the front right, above, framing the domain
  --camera-target X,Y,Z default: the domain's centre
  --camera-up X,Y,Z     default: 0,1,0
  --fov DEG             vertical field of view, (1, 170) (default 40)
  --width W, --height H image size, 1..4096 (default 512 x 512)
  --shading MODE        lit|normals|gradient_error|thickness (default lit; thickness tints
                        walls under 1 vu red)
  --quality Q           JPEG quality 1..100 (default 90)

Reports:
  --stats               after the last operation, one JSON line on stdout: revision,
                        inside_volume, surface_area, components, bounds {empty, lo, hi},
                        gradient_error {max, mean, voxels}, digest (as session.stats gives
                        them), ms (time spent in operations)
  --stats-every K       a stats line after every K operations (and after the last)
  --threads N           worker threads, 0 = one per core (default); results do not depend on N

Exit status: 0 success; 1 bad input (reported as OPS.jsonl:LINE: reason, or FILE: reason);
2 usage error.
)";
}

int runBatch(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (std::find(args.begin(), args.end(), "--help") != args.end() ||
      std::find(args.begin(), args.end(), "-h") != args.end()) {
    printBatchUsage(out);
    return kExitOk;
  }
  try {
    return run(args, out);
  } catch (const UsageError& e) {
    err << "marzipan batch: " << e.what() << "\n(marzipan batch --help lists the options)\n";
    return kExitUsage;
  } catch (const InputError& e) {
    err << e.what() << '\n';
    return kExitBadInput;
  } catch (const EngineError& e) {
    err << "marzipan batch: " << e.what() << '\n';
    return kExitBadInput;
  }
}

}  // namespace marzipan::service
