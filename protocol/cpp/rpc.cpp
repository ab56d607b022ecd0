// The JSON-RPC envelope and params decoders of rpc.hpp. Every refusal names the field the way
// it appears in the message (json_checks.hpp).
#include "rpc.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "json_checks.hpp"

namespace marzipan::protocol {

using nlohmann::json;
using namespace checks;

bool needsFrameId(Method m) {
  return m == Method::RenderFrame || m == Method::SplatsGet || m == Method::MeshExport || m == Method::VolumeSave ||
         m == Method::VolumeLoad;
}

bool isEdit(Method m) {
  return m == Method::ToolApply || m == Method::StrokeBegin || m == Method::StrokeDabs || m == Method::StrokeEnd ||
         m == Method::VolumeMorph || m == Method::HistoryUndo || m == Method::HistoryRedo || m == Method::VolumeLoad ||
         m == Method::MaskClear || m == Method::MaskInvert || m == Method::MaskFill;
}

MaskAction maskActionOf(Method m) {
  return m == Method::MaskInvert ? MaskAction::Invert : m == Method::MaskFill ? MaskAction::Fill : MaskAction::Clear;
}

namespace {

constexpr std::int64_t kMaxSafeInteger = (std::int64_t(1) << 53) - 1;

bool idCharsOnly(std::string_view s) {
  for (const char c : s) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

ParsedRequest refuse(RpcCode code, std::string message, json id = nullptr, bool notification = false,
                     json data = nullptr) {
  ParsedRequest out;
  out.error = RpcError{code, std::move(message), std::move(data), std::move(id), notification};
  return out;
}

// An id PROTOCOL.md accepts: a string, or an integer within +-(2^53-1).
bool validId(const json& id) {
  if (id.is_string()) return true;
  if (id.is_number_unsigned()) return id.get<std::uint64_t>() <= std::uint64_t(kMaxSafeInteger);
  if (id.is_number_integer()) return std::abs(id.get<std::int64_t>()) <= kMaxSafeInteger;
  return false;
}

ViewMode viewModeValue(const json& v, bool framesAllowed) {
  const std::string name = stringValue(v, "view");
  const auto mode = fromWireName(kViewModeNames, name);
  if (!mode || (!framesAllowed && *mode == ViewMode::Frames))
    fail("view", std::string("must be ") + (framesAllowed ? "\"splats\", \"frames\" or \"none\"" : "\"splats\" or \"none\"") +
                     ", got " + inQuotes(name));
  return *mode;
}

std::optional<int> protocolValue(const json& params) {
  const json* p = find(params, "protocol");
  if (!p) return std::nullopt;
  return int(integerInRange(*p, "protocol", 0, 1 << 30));
}

RayParam rayValue(const json& v, std::string_view key) {
  if (!v.is_object()) fail(key, "must be an object {origin, direction}, got " + describe(v));
  try {
    checkKeys(v, {"origin", "direction"}, "a ray");
    RayParam r;
    r.origin = vec3Value(require(v, "origin", "a ray"), "origin", kMaxCoordinate);
    r.direction = vec3Value(require(v, "direction", "a ray"), "direction", 1e300);
    if (r.direction == Vec3{0, 0, 0}) fail("direction", "must not be zero");
    return r;
  } catch (const OpError& e) {
    // Nested values are reported under the top-level key, the message says which part.
    throw OpError(std::string(key), inQuotes(key) + ": " + e.message());
  }
}

// The camera object {eye, target, up?, fov?} of view.set, render.frame and presence.
Camera cameraObject(const json& c) {
  if (!c.is_object()) fail("camera", "must be an object {eye, target, up?, fov?}, got " + describe(c));
  Camera cam;
  try {
    checkKeys(c, {"eye", "target", "up", "fov"}, "a camera");
    cam.eye = vec3Value(require(c, "eye", "a camera"), "eye", 1e5);
    cam.target = vec3Value(require(c, "target", "a camera"), "target", 1e5);
    if (const json* up = find(c, "up")) cam.up = vec3Value(*up, "up", 1e300);
    if (const json* fov = find(c, "fov")) {
      cam.fovY_degrees = finiteNumber(*fov, "fov");
      if (!(cam.fovY_degrees > 1 && cam.fovY_degrees < 170))
        fail("fov", "must be in (1, 170) degrees, got " + formatNumber(cam.fovY_degrees));
    }
  } catch (const OpError& e) {
    throw OpError("camera", "\"camera\": " + e.message());
  }
  return cam;
}

Camera cameraValue(const json& params, int maxSide) {
  const std::string context = "a frame";
  Camera cam = cameraObject(require(params, "camera", context));
  for (const char* key : {"width", "height"}) {
    const std::int64_t side = integerInRange(require(params, key, context), key, 1, std::int64_t(1) << 31);
    if (side > maxSide)
      throw RpcException(RpcCode::LimitExceeded,
                         inQuotes(key) + " " + std::to_string(side) + " is over the server's max_frame_side " +
                             std::to_string(maxSide),
                         {{"limit", "max_frame_side"}, {"value", side}, {"max", maxSide}, {"field", key}});
    (std::string_view(key) == "width" ? cam.width : cam.height) = int(side);
  }
  try {
    cam.validate();
  } catch (const std::exception& e) {
    throw RpcException(RpcCode::EngineRefused, std::string("\"camera\": ") + e.what(), {{"field", "camera"}});
  }
  return cam;
}

Shading shadingValue(const json& v) {
  const std::string shading = stringValue(v, "shading");
  if (const auto s = shadingFromName(shading)) return *s;
  fail("shading", "must be \"lit\", \"normals\", \"gradient_error\" or \"thickness\", got " + inQuotes(shading));
}

// "min_vu" of the thickness shading: a wall thinner than this is drawn red.
std::optional<double> minVuValue(const json& params, Shading shading) {
  const json* m = find(params, "min_vu");
  if (!m) return std::nullopt;
  if (shading != Shading::Thickness) fail("min_vu", "applies to shading \"thickness\" only");
  const double v = finiteNumber(*m, "min_vu");
  if (!(v > 0 && v <= 1e4)) fail("min_vu", "must be a number of vu above 0 and at most 10000");
  return v;
}

std::string paramsContext(Method m) { return "params of " + std::string(nameOf(kMethodNames, m)); }

// "splats" of session.create and session.join: the splat buffer version the client reads.
int splatsVersionValue(const json& params) {
  const json* s = find(params, "splats");
  return s ? int(integerInRange(*s, "splats", 1, kSplatsVersionNewest)) : kSplatsVersionDefault;
}

}  // namespace

bool isSessionId(std::string_view s) { return !s.empty() && s.size() <= 64 && idCharsOnly(s); }
bool isToken(std::string_view s) { return !s.empty() && s.size() <= 128 && idCharsOnly(s); }

ParsedRequest parseRequest(std::string_view text) {
  json message;
  try {
    message = parseJsonText(text);
  } catch (const OpError& e) {
    return refuse(RpcCode::ParseError, "parse error: " + e.message());
  }
  if (message.is_array()) return refuse(RpcCode::InvalidRequest, "batches (JSON arrays) are not supported");
  if (!message.is_object()) return refuse(RpcCode::InvalidRequest, "a request must be a JSON object, got " + describe(message));

  // The id first, so that later refusals can name it.
  const json* id = find(message, "id");
  const bool notification = id == nullptr;
  json replyId = nullptr;
  if (id) {
    if (!validId(*id))
      return refuse(RpcCode::InvalidRequest,
                    "\"id\" must be a string or an integer within +-(2^53-1), got " + describe(*id));
    replyId = *id;
  }
  for (const auto& item : message.items()) {
    const std::string& k = item.key();
    if (k != "jsonrpc" && k != "id" && k != "method" && k != "params")
      return refuse(RpcCode::InvalidRequest, "unknown key " + inQuotes(k) + " in a request (allowed: jsonrpc, id, method, params)",
                    replyId, notification);
  }
  const json* version = find(message, "jsonrpc");
  if (!version || *version != "2.0")
    return refuse(RpcCode::InvalidRequest, "\"jsonrpc\" must be \"2.0\"", replyId, notification);
  const json* method = find(message, "method");
  if (!method || !method->is_string())
    return refuse(RpcCode::InvalidRequest,
                  method ? "\"method\" must be a string, got " + describe(*method) : "\"method\" is missing", replyId,
                  notification);
  const std::string& name = method->get_ref<const std::string&>();
  const auto m = fromWireName(kMethodNames, name);
  if (!m) return refuse(RpcCode::UnknownMethod, "unknown method " + inQuotes(name), replyId, notification);

  Request request;
  request.id = id ? std::optional<json>(*id) : std::nullopt;
  request.method = *m;
  if (const json* params = find(message, "params")) {
    if (!params->is_object())
      return refuse(RpcCode::InvalidParams, "\"params\" must be an object (by-name parameters), got " + describe(*params),
                    replyId, notification, {{"field", "params"}});
    // Moved, not copied: a request's params are most of it, and presence comes at pointer rate.
    request.params = std::move(message["params"]);
  }
  if (needsFrameId(*m) && id) {
    const bool ok = id->is_number_integer() && !id->is_number_float() &&
                    (id->is_number_unsigned() ? id->get<std::uint64_t>() >= 1 && id->get<std::uint64_t>() <= 0xFFFFFFFFu
                                              : id->get<std::int64_t>() >= 1 && id->get<std::int64_t>() <= 0xFFFFFFFF);
    if (!ok)
      return refuse(RpcCode::InvalidRequest,
                    inQuotes(name) + " needs an integer id in [1, 4294967295]: it travels in the binary frame header",
                    replyId, notification);
    request.frameId = std::uint32_t(id->get<std::uint64_t>());
  }
  ParsedRequest out;
  out.request = std::move(request);
  return out;
}

namespace {

// One pass over JSON text (RFC 8259) that builds nothing: each skip moves `at` past one value
// and says whether it was well formed. Recursion is one level per array or object, at most
// kMaxJsonDepth.
class Skimmer {
 public:
  explicit Skimmer(std::string_view text) : t_(text) {}
  std::size_t at = 0;

  void space() {
    while (at < t_.size() && (t_[at] == ' ' || t_[at] == '\t' || t_[at] == '\n' || t_[at] == '\r')) ++at;
  }
  bool eat(char c) {
    space();
    if (at >= t_.size() || t_[at] != c) return false;
    ++at;
    return true;
  }
  bool next(char c) {
    space();
    return at < t_.size() && t_[at] == c;
  }
  // `raw`: the bytes between the quotes, escapes as written.
  bool string(std::string_view* raw = nullptr) {
    if (!next('"')) return false;
    const std::size_t start = ++at;
    while (at < t_.size()) {
      const auto c = static_cast<unsigned char>(t_[at]);
      if (c == '"') {
        if (raw) *raw = t_.substr(start, at - start);
        ++at;
        return true;
      }
      if (c < 0x20) return false;
      if (c == '\\') {
        if (++at >= t_.size()) return false;
        if (t_[at] == 'u') {
          for (int k = 0; k < 4; ++k)
            if (++at >= t_.size() || !std::isxdigit(static_cast<unsigned char>(t_[at]))) return false;
        } else if (std::string_view("\"\\/bfnrt").find(t_[at]) == std::string_view::npos) {
          return false;
        }
      }
      ++at;
    }
    return false;
  }
  // The value starting at `at`, inside `depth` arrays and objects.
  bool value(int depth) {
    if (next('"')) return string();
    if (at >= t_.size()) return false;
    switch (t_[at]) {
      case '{': return object(depth + 1);
      case '[': return array(depth + 1);
      case 't': return literal("true");
      case 'f': return literal("false");
      case 'n': return literal("null");
      default: return number();
    }
  }

 private:
  std::string_view t_;

  bool digits() {
    const std::size_t start = at;
    while (at < t_.size() && t_[at] >= '0' && t_[at] <= '9') ++at;
    return at > start;
  }
  bool number() {
    if (at < t_.size() && t_[at] == '-') ++at;
    if (at < t_.size() && t_[at] == '0') ++at;
    else if (!digits()) return false;
    if (at < t_.size() && t_[at] == '.' && (++at, !digits())) return false;
    if (at < t_.size() && (t_[at] == 'e' || t_[at] == 'E')) {
      ++at;
      if (at < t_.size() && (t_[at] == '+' || t_[at] == '-')) ++at;
      if (!digits()) return false;
    }
    return true;
  }
  bool literal(std::string_view word) {
    if (t_.substr(at, word.size()) != word) return false;
    at += word.size();
    return true;
  }
  bool array(int depth) {
    if (depth > kMaxJsonDepth) return false;
    ++at;
    if (eat(']')) return true;
    do {
      if (!value(depth)) return false;
    } while (eat(','));
    return eat(']');
  }
  bool object(int depth) {
    if (depth > kMaxJsonDepth) return false;
    ++at;
    if (eat('}')) return true;
    do {
      if (!string() || !eat(':') || !value(depth)) return false;
    } while (eat(','));
    return eat('}');
  }
};

// Whether a key, as written between its quotes, reads "id": escaped, "id" is at most 12 bytes.
bool isIdKey(std::string_view raw) {
  if (raw.find('\\') == std::string_view::npos) return raw == "id";
  if (raw.size() > 12) return false;
  const std::string quoted = "\"" + std::string(raw) + "\"";
  const json key = json::parse(quoted, nullptr, false);
  return key.is_string() && key.get_ref<const std::string&>() == "id";
}

}  // namespace

std::optional<PeekedId> peekRequestId(std::string_view text) {
  Skimmer s(text);
  if (text.substr(0, 3) == "\xEF\xBB\xBF") s.at = 3;  // nlohmann skips a byte order mark
  if (!s.next('{')) return std::nullopt;
  ++s.at;
  std::optional<std::string_view> idText;
  if (!s.eat('}')) {
    do {
      std::string_view key;
      if (!s.string(&key) || !s.eat(':')) return std::nullopt;
      s.space();
      const std::size_t start = s.at;
      if (!s.value(1)) return std::nullopt;
      if (isIdKey(key)) {
        if (idText) return std::nullopt;
        idText = text.substr(start, s.at - start);
      }
    } while (s.eat(','));
    if (!s.eat('}')) return std::nullopt;
  }
  s.space();
  // nlohmann's reader ends the text at a NUL byte, so parseRequest reads whatever follows one as
  // nothing: so does the peek.
  if (s.at != text.size() && text[s.at] != '\0') return std::nullopt;
  if (!idText) return PeekedId{nullptr, true};
  PeekedId out;
  if (idText->size() <= kMaxPeekedIdBytes) {
    json id = json::parse(*idText, nullptr, false);
    if (id.is_discarded()) return std::nullopt;  // e.g. invalid UTF-8 in a string: no valid request
    if (validId(id)) out.id = std::move(id);
  }
  return out;
}

CreateParams parseCreateParams(const json& params) {
  const std::string context = paramsContext(Method::SessionCreate);
  checkKeys(params, {"size", "solid", "session", "protocol", "view", "name", "base_color", "splats"}, context);
  CreateParams p;
  const json& size = require(params, "size", context);
  if (!size.is_array() || size.size() != 3)
    fail("size", "must be an array of three integers [nx, ny, nz], got " +
                     (size.is_array() ? "an array of " + std::to_string(size.size()) : describe(size)));
  for (int a = 0; a < 3; ++a) {
    try {
      p.size[a] = int(integerInRange(size[std::size_t(a)], "size", 8, kMaxDomainSide));
    } catch (const OpError& e) {
      throw OpError("size", elementName("size", std::size_t(a)) + e.message().substr(6));
    }
  }
  const std::string solid = stringValue(require(params, "solid", context), "solid");
  const auto kind = solidKindFromName(solid);
  if (!kind) fail("solid", "must be one of empty, sphere, box, torus, cylinder, dumbbell, pig, got " + inQuotes(solid));
  p.solid = *kind;
  if (const json* s = find(params, "session")) {
    const std::string id = stringValue(*s, "session");
    // The answers to session.join tell whether an id exists (-32001 vs -32002): that is safe
    // only for ids nobody can guess, so a proposed id must be able to carry 128 random bits.
    if (id.size() < 22 || id.size() > 64 || !idCharsOnly(id))
      fail("session", "must be 22 to 64 characters of A-Z a-z 0-9 _ - (at least 128 random bits: 22 random "
                      "base64url characters), got " + inQuotes(id));
    p.session = id;
  }
  p.protocol = protocolValue(params);
  if (const json* v = find(params, "view")) p.view = viewModeValue(*v, false);
  if (const json* n = find(params, "name")) p.name = nameValue(*n);
  if (const json* c = find(params, "base_color")) p.baseColor = colorValue(*c, "base_color");
  p.splats = splatsVersionValue(params);
  return p;
}

JoinParams parseJoinParams(const json& params) {
  const std::string context = paramsContext(Method::SessionJoin);
  checkKeys(params, {"session", "token", "protocol", "view", "name", "splats"}, context);
  JoinParams p;
  p.session = stringValue(require(params, "session", context), "session");
  if (!isSessionId(p.session)) fail("session", "must be 1 to 64 characters of A-Z a-z 0-9 _ -, got " + inQuotes(p.session));
  p.token = stringValue(require(params, "token", context), "token");
  if (!isToken(p.token)) fail("token", "must be 1 to 128 characters of A-Z a-z 0-9 _ -");
  p.protocol = protocolValue(params);
  if (const json* v = find(params, "view")) p.view = viewModeValue(*v, false);
  if (const json* n = find(params, "name")) p.name = nameValue(*n);
  p.splats = splatsVersionValue(params);
  return p;
}

ToolApplyParams parseToolApplyParams(const json& params) {
  if (find(params, "op")) fail("op", "is not for tool.apply: operations with \"op\" go to volume.morph, global smoothing is {\"tool\":\"smooth\",\"global\":true,...}");
  ToolApplyParams p;
  const json* ray = find(params, "ray");
  if (!ray) {
    p.op = parseOp(params);
    return p;
  }
  if (find(params, "center")) fail("center", "and \"ray\" exclude each other: give one");
  p.ray = rayValue(*ray, "ray");
  json withCenter = params;
  withCenter.erase("ray");
  withCenter["center"] = json::array({0, 0, 0});
  p.op = parseOp(withCenter);
  if (std::holds_alternative<GlobalSmoothOp>(p.op)) fail("ray", "is not for global smoothing, which has no centre");
  return p;
}

StrokeBeginParams parseStrokeBeginParams(const json& params) {
  const std::string context = paramsContext(Method::StrokeBegin);
  checkKeys(params, kStrokeBeginKeys, context);
  StrokeBeginParams p;
  const std::string tool = stringValue(require(params, "tool", context), "tool");
  const ToolSpec* spec = findTool(kTools, tool);
  const auto t = fromWireName(kBrushToolNames, tool);
  const auto warp = fromWireName(kWarpToolNames, tool);
  const auto paint = fromWireName(kPaintToolNames, tool);
  if (!spec || !spec->strokes || !(t || warp || paint)) {
    std::vector<std::string_view> strokes;
    for (const ToolSpec& s : kTools)
      if (s.strokes) strokes.push_back(s.name);
    fail("tool", "must be one of " + listNames(strokes) + " for a stroke, got " + inQuotes(tool));
  }
  // A key of stroke.begin that some tools take but not this one.
  for (const auto& item : params.items()) {
    const std::string& key = item.key();
    if (key == "tool" || key == "symmetry" || key == "accumulate" || hasKey(spec->strokeKeys, key)) continue;
    std::vector<std::string_view> takers;
    for (const ToolSpec& s : kTools)
      if (hasKey(s.strokeKeys, key)) takers.push_back(s.name);
    fail(key, "is only for " + listNames(takers) + ", not " + inQuotes(tool));
  }
  if (warp) {
    // A warp moves the volume as the stroke began by one field: it has no mirror images, and
    // nothing to accumulate (PROTOCOL.md, warp strokes).
    for (const std::string_view flag : {"symmetry", "accumulate"})
      if (find(params, flag)) fail(flag, "is not for warp tools (" + inQuotes(tool) + " moves the volume as the stroke began)");
    WarpBeginParams w;
    w.tool = *warp;
    if (hasKey(spec->strokeKeys, kParamVolume.key)) w.volume = numberParam(params, kParamVolume, context);
    if (hasKey(spec->strokeKeys, kParamDirection.key)) w.direction = vectorParam(params, kParamDirection);
    p.warp = w;
    p.radius = numberParam(params, radiusParamOf(*warp), context);
    p.strength = numberParam(params, kParamStrength, context);
    return p;
  }
  if (paint) {
    PaintBeginParams pb;
    pb.tool = *paint;
    if (hasKey(spec->strokeKeys, kParamPaintColor.key)) pb.color = *colorParam(params, kParamPaintColor, context);
    pb.hardness = numberParam(params, kParamHardness, context);
    if (hasKey(spec->strokeKeys, kParamErase.key)) pb.erase = booleanParam(params, kParamErase);
    p.paint = pb;
  } else {
    p.tool = *t;
  }
  p.radius = numberParam(params, kParamRadius, context);
  p.strength = numberParam(params, kParamStrength, context);
  if (const json* sym = find(params, "symmetry")) {
    if (!sym->is_array() || sym->size() > 3) fail("symmetry", "must be an array of axes such as [\"x\", \"z\"], got " + describe(*sym));
    for (const json& axis : *sym) {
      const std::string a = axis.is_string() ? axis.get<std::string>() : std::string();
      bool& flag = a == "x" ? p.mirrorX : a == "y" ? p.mirrorY : p.mirrorZ;
      if (a != "x" && a != "y" && a != "z") fail("symmetry", "lists axes \"x\", \"y\", \"z\", got " + describe(axis));
      if (flag) fail("symmetry", "names axis " + inQuotes(a) + " twice");
      flag = true;
    }
  }
  if (const json* a = find(params, "accumulate")) p.accumulate = booleanValue(*a, "accumulate");
  if (find(params, kParamHeight.key)) {
    if (p.accumulate) fail("height", "is for strokes that remember what they applied, not with \"accumulate\": true");
    p.height = numberParam(params, kParamHeight, context, p.radius);
  }
  return p;
}

StrokeDabsParams parseStrokeDabsParams(const json& params, std::size_t maxDabs) {
  const std::string context = paramsContext(Method::StrokeDabs);
  checkKeys(params, {"stroke", "dabs"}, context);
  StrokeDabsParams p;
  p.stroke = std::uint64_t(integerInRange(require(params, "stroke", context), "stroke", 1, kMaxSafeInteger));
  const json& dabs = require(params, "dabs", context);
  if (!dabs.is_array()) fail("dabs", "must be an array of dabs, got " + describe(dabs));
  if (dabs.empty()) fail("dabs", "must hold at least one dab");
  if (dabs.size() > maxDabs)
    throw RpcException(RpcCode::LimitExceeded,
                       "\"dabs\" holds " + std::to_string(dabs.size()) + " dabs, over the server's max_dabs " +
                           std::to_string(maxDabs),
                       {{"limit", "max_dabs"}, {"value", dabs.size()}, {"max", maxDabs}, {"field", "dabs"}});
  p.dabs.reserve(dabs.size());
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const json& d = dabs[i];
    try {
      if (!d.is_object()) fail("dab", "must be an object {center | ray, pressure?}, got " + describe(d));
      checkKeys(d, {"center", "ray", "pressure"}, "a dab");
      const json* center = find(d, "center");
      const json* ray = find(d, "ray");
      if ((center != nullptr) == (ray != nullptr)) fail("dab", "needs exactly one of \"center\" and \"ray\"");
      DabParam dab;
      if (center) dab.at = vec3Value(*center, "center", kMaxCoordinate);
      else dab.at = rayValue(*ray, "ray");
      if (const json* pr = find(d, "pressure")) {
        dab.pressure = finiteNumber(*pr, "pressure");
        if (!(dab.pressure > 0 && dab.pressure <= 1)) fail("pressure", "must be in (0, 1], got " + formatNumber(dab.pressure));
      }
      p.dabs.push_back(dab);
    } catch (const OpError& e) {
      throw OpError("dabs", elementName("dabs", i) + ": " + e.message());
    }
  }
  return p;
}

std::uint64_t parseStrokeEndParams(const json& params) {
  const std::string context = paramsContext(Method::StrokeEnd);
  checkKeys(params, {"stroke"}, context);
  return std::uint64_t(integerInRange(require(params, "stroke", context), "stroke", 1, kMaxSafeInteger));
}

MorphOp parseMorphParams(const json& params) {
  const std::string context = paramsContext(Method::VolumeMorph);
  std::vector<std::string_view> keys{"kind"};
  keys.insert(keys.end(), kMorphKeys.begin(), kMorphKeys.end());
  checkKeys(params, keys, context);
  json op = params;
  op["op"] = "morph";
  return std::get<MorphOp>(parseOp(op));
}

ViewSetParams parseViewSetParams(const json& params, int maxSide) {
  const std::string context = paramsContext(Method::ViewSet);
  checkKeys(params, {"mode", "camera", "width", "height", "shading", "min_vu"}, context);
  ViewSetParams p;
  const std::string mode = stringValue(require(params, "mode", context), "mode");
  const auto m = fromWireName(kViewModeNames, mode);
  if (!m) fail("mode", "must be \"splats\", \"frames\" or \"none\", got " + inQuotes(mode));
  p.mode = *m;
  if (p.mode == ViewMode::Frames) {
    p.camera = cameraValue(params, maxSide);
    if (const json* s = find(params, "shading")) p.shading = shadingValue(*s);
    if (const auto minVu = minVuValue(params, p.shading)) p.minVu = *minVu;
  } else {
    for (const char* key : {"camera", "width", "height", "shading", "min_vu"})
      if (find(params, key)) fail(key, "is only for mode \"frames\"");
  }
  return p;
}

RenderFrameParams parseRenderFrameParams(const json& params, int maxSide) {
  const std::string context = paramsContext(Method::RenderFrame);
  checkKeys(params, {"camera", "width", "height", "format", "quality", "shading", "min_vu", "revision"}, context);
  RenderFrameParams p;
  if (const json* rev = find(params, "revision")) p.revision = std::uint64_t(integerInRange(*rev, "revision", 0, kMaxSafeInteger));
  const std::string format = stringValue(require(params, "format", context), "format");
  if (format == "jpeg") p.format = ImageKind::Jpeg;
  else if (format == "png") p.format = ImageKind::Png;
  else fail("format", "must be \"jpeg\" or \"png\", got " + inQuotes(format));
  if (const json* q = find(params, "quality")) {
    if (p.format != ImageKind::Jpeg) fail("quality", "applies to format \"jpeg\" only");
    p.quality = int(integerInRange(*q, "quality", 1, 100));
  }
  if (const json* s = find(params, "shading")) p.shading = shadingValue(*s);
  if (const auto m = minVuValue(params, p.shading)) p.minVu = *m;
  p.camera = cameraValue(params, maxSide);
  return p;
}

MeshExportParams parseMeshExportParams(const json& params) {
  const std::string context = paramsContext(Method::MeshExport);
  checkKeys(params, {"format", "max_triangles", "max_error"}, context);
  MeshExportParams p;
  p.format = stringValue(require(params, "format", context), "format");
  if (p.format != "stl" && p.format != "obj" && p.format != "ply" && p.format != "glb")
    fail("format", "must be \"stl\", \"obj\", \"ply\" or \"glb\", got " + inQuotes(p.format));
  if (const json* t = find(params, "max_triangles"))
    p.maxTriangles = std::uint32_t(integerInRange(*t, "max_triangles", 1, 0xFFFFFFFFll));
  if (const json* e = find(params, "max_error")) {
    p.maxError = finiteNumber(*e, "max_error");
    if (!(*p.maxError > 0 && *p.maxError <= 1e6)) fail("max_error", "must be a number of vu above 0 and at most 1e6");
  }
  return p;
}

ThicknessParams parseThicknessParams(const json& params) {
  const std::string context = paramsContext(Method::AnalysisThickness);
  checkKeys(params, {"min_vu", "max_places"}, context);
  ThicknessParams p;
  p.minVu = finiteNumber(require(params, "min_vu", context), "min_vu");
  if (!(p.minVu > 0 && p.minVu <= 1e4)) fail("min_vu", "must be a number of vu above 0 and at most 10000");
  if (const json* m = find(params, "max_places")) p.maxPlaces = std::uint32_t(integerInRange(*m, "max_places", 1, 1000));
  return p;
}

std::string_view volumeFormatName(VolumeFormat f) { return f == VolumeFormat::Vdb ? "vdb" : "mzv"; }

namespace {

VolumeFormat volumeFormatParam(const json& params) {
  const json* f = find(params, "format");
  if (!f) return VolumeFormat::Mzv;
  const std::string v = stringValue(*f, "format");
  if (v == "mzv") return VolumeFormat::Mzv;
  if (v == "vdb") return VolumeFormat::Vdb;
  fail("format", "must be \"mzv\" or \"vdb\", got " + inQuotes(v));
}

}  // namespace

VolumeFormat parseVolumeSaveParams(const json& params) {
  checkKeys(params, {"format"}, paramsContext(Method::VolumeSave));
  return volumeFormatParam(params);
}

VolumeLoadParams parseVolumeLoadParams(const json& params, std::uint64_t maxBytes) {
  const std::string context = paramsContext(Method::VolumeLoad);
  checkKeys(params, {"bytes", "format"}, context);
  VolumeLoadParams p;
  p.format = volumeFormatParam(params);
  const std::int64_t bytes = integerInRange(require(params, "bytes", context), "bytes", 52, kMaxSafeInteger);
  if (std::uint64_t(bytes) > maxBytes)
    throw RpcException(RpcCode::LimitExceeded,
                       "\"bytes\" " + std::to_string(bytes) + " is over the largest upload, " + std::to_string(maxBytes),
                       {{"limit", "max_binary_bytes"}, {"value", bytes}, {"max", maxBytes}, {"field", "bytes"}});
  p.bytes = std::uint64_t(bytes);
  return p;
}

HistoryScope parseHistoryParams(const json& params, Method m) {
  checkKeys(params, {"scope"}, paramsContext(m));
  const json* scope = find(params, "scope");
  if (!scope) return HistoryScope::Session;
  const std::string v = stringValue(*scope, "scope");
  if (v == "session") return HistoryScope::Session;
  if (v == "mine") return HistoryScope::Mine;
  fail("scope", "must be \"session\" or \"mine\", got " + inQuotes(v));
}

std::optional<std::uint64_t> parseForkParams(const json& params) {
  checkKeys(params, {"revision"}, paramsContext(Method::SessionFork));
  const json* revision = find(params, "revision");
  if (!revision) return std::nullopt;
  return std::uint64_t(integerInRange(*revision, "revision", 0, kMaxSafeInteger));
}

HistoryListParams parseHistoryListParams(const json& params) {
  checkKeys(params, {"before", "limit"}, paramsContext(Method::HistoryList));
  HistoryListParams p;
  if (const json* before = find(params, "before")) p.before = std::uint64_t(integerInRange(*before, "before", 1, kMaxSafeInteger));
  if (const json* limit = find(params, "limit"))
    p.limit = std::size_t(integerInRange(*limit, "limit", 1, std::int64_t(kMaxHistoryListLimit)));
  return p;
}

void parseNoParams(const json& params, Method m) { checkKeys(params, {}, paramsContext(m) + ", which takes none"); }

// --- presence ----------------------------------------------------------------------------------

namespace {

// The code points of valid UTF-8 (the transport and the JSON parser checked it).
std::vector<char32_t> codePoints(std::string_view s) {
  std::vector<char32_t> out;
  for (std::size_t i = 0; i < s.size();) {
    const auto b = static_cast<unsigned char>(s[i]);
    const int n = b < 0x80 ? 1 : b < 0xE0 ? 2 : b < 0xF0 ? 3 : 4;
    char32_t c = n == 1 ? b : n == 2 ? (b & 0x1F) : n == 3 ? (b & 0x0F) : (b & 0x07);
    for (int k = 1; k < n && i + std::size_t(k) < s.size(); ++k) c = c << 6 | (static_cast<unsigned char>(s[i + std::size_t(k)]) & 0x3F);
    out.push_back(c);
    i += std::size_t(n);
  }
  return out;
}

// White space (Unicode's space separators): trimmed at both ends of a name, kept inside it.
bool isSpace(char32_t c) {
  return c == ' ' || c == 0xA0 || c == 0x1680 || (c >= 0x2000 && c <= 0x200A) || c == 0x202F || c == 0x205F ||
         c == 0x3000;
}

// Characters a name must not hold: they would break or reorder the text around it in a UI.
bool isControl(char32_t c) {
  return c < 0x20 || (c >= 0x7F && c <= 0x9F) || c == 0x2028 || c == 0x2029 || (c >= 0x202A && c <= 0x202E) ||
         (c >= 0x2066 && c <= 0x2069);
}

// Characters that show nothing, or a blank, wherever they stand: a name holding them could
// look blank or the same as another name ("Ada" and "Ada" + U+200E). Zero width space,
// (non-)joiner and direction marks, word joiner and invisible operators, the Arabic letter mark,
// byte order mark, soft hyphen, combining grapheme joiner, Mongolian vowel separator, the
// Khmer inherent vowels, the deprecated format characters, the Hangul fillers and the blank
// braille pattern.
bool isInvisible(char32_t c) {
  return c == 0xAD || c == 0x34F || c == 0x61C || c == 0x115F || c == 0x1160 || c == 0x17B4 || c == 0x17B5 ||
         c == 0x180E || (c >= 0x200B && c <= 0x200F) || (c >= 0x2060 && c <= 0x2064) || (c >= 0x206A && c <= 0x206F) ||
         c == 0x2800 || c == 0x3164 || c == 0xFEFF || c == 0xFFA0;
}

// Characters that only change the look of the one before them (variation selectors, the tag
// characters of flag emoji): allowed, but they are not what makes a name visible.
bool isModifierOnly(char32_t c) {
  return (c >= 0xFE00 && c <= 0xFE0F) || (c >= 0xE0000 && c <= 0xE007F) || (c >= 0xE0100 && c <= 0xE01EF);
}

std::string codePointText(char32_t c) {
  char buf[12];
  std::snprintf(buf, sizeof buf, "U+%04X", unsigned(c));
  return buf;
}

}  // namespace

std::string nameValue(const json& v) {
  const std::string raw = stringValue(v, "name");
  const std::vector<char32_t> cps = codePoints(raw);
  std::size_t lo = 0, hi = cps.size();
  while (lo < hi && isSpace(cps[lo])) ++lo;
  while (hi > lo && isSpace(cps[hi - 1])) --hi;
  if (hi - lo > kMaxNameChars)
    fail("name", "must be at most " + std::to_string(kMaxNameChars) + " characters, got " + std::to_string(hi - lo));
  bool visible = false;
  for (std::size_t i = lo; i < hi; ++i) {
    if (isControl(cps[i])) fail("name", "must not hold control characters (" + codePointText(cps[i]) + ")");
    if (isInvisible(cps[i])) fail("name", "must not hold invisible characters (" + codePointText(cps[i]) + ")");
    visible = visible || !(isSpace(cps[i]) || isModifierOnly(cps[i]));
  }
  if (!visible) fail("name", "must hold at least one visible character");
  // Cut the raw bytes at the trimmed code points.
  std::size_t begin = 0, end = 0, index = 0;
  for (std::size_t i = 0; i <= raw.size(); ++index) {
    if (index == lo) begin = i;
    if (index == hi) {
      end = i;
      break;
    }
    const auto b = static_cast<unsigned char>(raw[i]);
    i += b < 0x80 ? 1 : b < 0xE0 ? 2 : b < 0xF0 ? 3 : 4;
  }
  return raw.substr(begin, end - begin);
}

PresenceParams parsePresenceParams(const json& params) {
  const std::string context = paramsContext(Method::Presence);
  checkKeys(params, {"brush", "camera"}, context);
  PresenceParams p;
  if (const json* b = find(params, "brush")) {
    if (!b->is_object()) fail("brush", "must be an object {tool, radius, point, normal, active, color?}, got " + describe(*b));
    try {
      const std::string what = "a brush";
      checkKeys(*b, {"tool", "radius", "point", "normal", "active", "color"}, what);
      BrushPresence brush;
      brush.tool = stringValue(require(*b, "tool", what), "tool");
      if (!findTool(kTools, brush.tool)) {
        std::vector<std::string_view> names;
        for (const ToolSpec& s : kTools) names.push_back(s.name);
        fail("tool", "must be one of " + listNames(names) + ", got " + inQuotes(brush.tool));
      }
      brush.radius = numberInRange(require(*b, "radius", what), "radius", kParamRadius.minimum, kParamRadius.maximum);
      brush.point = vec3Value(require(*b, "point", what), "point", kMaxCoordinate);
      const Vec3 n = vec3Value(require(*b, "normal", what), "normal", kMaxCoordinate);
      const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
      if (!(length > 1e-12)) fail("normal", "must not be zero");
      brush.normal = {n.x / length, n.y / length, n.z / length};
      brush.active = booleanValue(require(*b, "active", what), "active");
      if (const json* c = find(*b, "color")) brush.color = colorValue(*c, "color");
      p.brush = std::move(brush);
    } catch (const OpError& e) {
      throw OpError("brush", "\"brush\": " + e.message());
    }
  }
  if (const json* c = find(params, "camera")) {
    p.camera = cameraObject(*c);
    try {
      p.camera->validate();
    } catch (const std::exception& e) {
      fail("camera", std::string("\"camera\": ") + e.what());
    }
  }
  return p;
}

json colorJson(SrgbColor c) { return json::array({c.r, c.g, c.b}); }

json brushJson(const BrushPresence& b) {
  json j{{"tool", b.tool}, {"radius", b.radius}, {"point", vec3Json(b.point)}, {"normal", vec3Json(b.normal)},
         {"active", b.active}};
  if (b.color) j["color"] = colorJson(*b.color);
  return j;
}

json cameraJson(const Camera& c) {
  return {{"eye", vec3Json(c.eye)}, {"target", vec3Json(c.target)}, {"up", vec3Json(c.up)}, {"fov", c.fovY_degrees}};
}

namespace {

// A value as the texts below write it.
void appendDump(std::string& out, const json& v) { out += v.dump(-1, ' ', false, json::error_handler_t::replace); }

}  // namespace

// The envelopes are written around their parts' own texts, with the keys in the order json's
// objects keep them (sorted): the bytes an envelope object's dump gave, without the deep copy of
// the result or params into it (a notification and a response per message; they were 47K
// instructions of a stroke message, docs/benchmark-log.md, capacity, 2026-11-30).
std::string resultText(const json& id, const json& result) {
  return resultTextOfJson(id, result.dump(-1, ' ', false, json::error_handler_t::replace));
}

std::string resultTextOfJson(const json& id, std::string_view result) {
  std::string out = "{\"id\":";
  appendDump(out, id);
  out += ",\"jsonrpc\":\"2.0\",\"result\":";
  out += result;
  out += '}';
  return out;
}

std::string errorText(const json& id, RpcCode code, const std::string& message, const json& data) {
  json error{{"code", int(code)}, {"message", message}};
  if (!data.is_null()) error["data"] = data;
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"error", error}}.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string notificationText(std::string_view method, const json& params) {
  std::string out = "{\"jsonrpc\":\"2.0\",\"method\":";
  appendDump(out, json(method));
  out += ",\"params\":";
  appendDump(out, params);
  out += '}';
  return out;
}

namespace {

// A box as the dump of boxJson(b) writes it.
void appendBox(std::string& out, const Box& b) {
  if (b.empty()) {
    out += "null";
    return;
  }
  const auto corner = [&](const char* key, Int3 c) {
    out += key;
    out += std::to_string(c.x) + "," + std::to_string(c.y) + "," + std::to_string(c.z) + "]";
  };
  corner("{\"hi\":[", b.hi);
  corner(",\"lo\":[", b.lo);
  out += '}';
}

// ,"revision":r,"roi":box: the last keys, in sorted order, of a stroke result and of session.changed.
void appendRevisionRoi(std::string& out, std::uint64_t revision, const Box& roi) {
  out += ",\"revision\":";
  out += std::to_string(revision);
  out += ",\"roi\":";
  appendBox(out, roi);
}

}  // namespace

std::string strokeDabsResultJson(std::uint64_t revision, std::uint64_t applied, const Box& roi, const json& plane) {
  std::string out = "{\"applied\":";
  out += std::to_string(applied);
  if (!plane.is_null()) {
    out += ",\"plane\":";
    appendDump(out, plane);
  }
  appendRevisionRoi(out, revision, roi);
  out += '}';
  return out;
}

std::string sessionChangedText(std::uint64_t revision, int by, std::string_view cause, const Box& roi,
                               std::string_view digest, bool canUndo, bool canRedo) {
  // The params' keys in the order json's objects keep them (sorted), as notificationText writes
  // them: every edit sends this to every client, and building the object and dumping it took
  // ~27K instructions a stroke message (docs/benchmark-log.md, capacity, 2026-11-30).
  std::string out = "{\"jsonrpc\":\"2.0\",\"method\":\"session.changed\",\"params\":{\"by\":";
  out += std::to_string(by);
  out += ",\"can_redo\":";
  out += canRedo ? "true" : "false";
  out += ",\"can_undo\":";
  out += canUndo ? "true" : "false";
  out += ",\"cause\":";
  appendDump(out, json(cause));
  out += ",\"digest\":";
  appendDump(out, json(digest));
  appendRevisionRoi(out, revision, roi);
  out += "}}";
  return out;
}

json vec3Json(Vec3 v) { return json::array({v.x, v.y, v.z}); }

json boxJson(const Box& b) {
  if (b.empty()) return nullptr;
  return {{"lo", {b.lo.x, b.lo.y, b.lo.z}}, {"hi", {b.hi.x, b.hi.y, b.hi.z}}};
}

}  // namespace marzipan::protocol
