// glTF 2.0 binary export and import (conventions in gltf.hpp). The JSON chunk is written and
// read by hand: the engine links no JSON library; written, the document has a fixed shape, read,
// only the few members a triangle mesh needs are looked at.
#include "gltf.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "color_space.hpp"
#include "errors.hpp"
#include "little_endian.hpp"
#include "mesh_io.hpp"
#include "mesh_reading.hpp"

namespace marzipan {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr std::uint32_t kJsonChunk = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kBinChunk = 0x004E4942;   // "BIN\0"
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kFloat = 5126, kUnsignedInt = 5125;

// Nine significant digits: parsing gives back the same float, which the validator compares
// against the accessor's data.
std::string number(float f) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, f, std::chars_format::general, 9);
  return std::string(buf, r.ptr);
}

std::string vec3(const float v[3]) {
  std::string s = "[";
  for (int a = 0; a < 3; ++a) s.append(a ? "," : "").append(number(v[a]));
  return s.append("]");
}

// Unit normals per vertex: the mesh's own, normalized, or the area-weighted triangle normal.
std::vector<float> unitNormals(const Mesh& m) {
  std::vector<float> n(m.normals);
  std::vector<double> fallback;
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    float* p = &n[3 * v];
    const double l = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
    if (l > 1e-12 && std::isfinite(l)) {
      for (int a = 0; a < 3; ++a) p[a] = float(p[a] / l);
      continue;
    }
    if (fallback.empty()) {
      fallback.assign(m.positions.size(), 0.0);
      for (std::size_t t = 0; t < m.triangleCount(); ++t) {
        const std::uint32_t* i = &m.indices[3 * t];
        const Vec3 f = cross(m.position(i[1]) - m.position(i[0]), m.position(i[2]) - m.position(i[0]));
        for (int k = 0; k < 3; ++k)
          for (int a = 0; a < 3; ++a) fallback[3 * std::size_t(i[k]) + std::size_t(a)] += f[a];
      }
    }
    const Vec3 f = normalized(Vec3{fallback[3 * v], fallback[3 * v + 1], fallback[3 * v + 2]});
    const bool ok = length(f) > 0.5;
    p[0] = ok ? float(f.x) : 0.0f, p[1] = ok ? float(f.y) : 0.0f, p[2] = ok ? float(f.z) : 1.0f;
  }
  return n;
}

}  // namespace

std::vector<std::uint8_t> exportGlb(const Mesh& m) {
  requireExportable(m);
  for (const float f : m.positions)
    if (!std::isfinite(f)) throw EngineError(ErrorKind::InvalidArgument, "mesh", "positions must be finite");
  const std::size_t vertices = m.vertexCount(), indexCount = m.indices.size();
  const bool hasNormals = !m.normals.empty(), hasColors = !m.colors.empty();
  const std::size_t positionBytes = 12 * vertices, normalBytes = hasNormals ? positionBytes : 0;
  const std::size_t colorBytes = hasColors ? positionBytes : 0;
  const std::size_t indexBytes = 4 * indexCount;
  const std::size_t binBytes = positionBytes + normalBytes + colorBytes + indexBytes;  // each a multiple of 4
  if (binBytes > std::numeric_limits<std::uint32_t>::max() / 2)
    throw EngineError(ErrorKind::TooLarge, "mesh", "the mesh needs more than 2 GiB of glTF buffer");

  std::string json = R"({"asset":{"version":"2.0","generator":"Marzipan"},"scene":0,)";
  if (vertices == 0 || indexCount == 0) {
    // glTF forbids empty accessors: an empty solid is a scene without nodes.
    json += R"("scenes":[{}]})";
  } else {
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = m.positions[std::size_t(a)];
    for (std::size_t v = 0; v < vertices; ++v)
      for (int a = 0; a < 3; ++a) {
        const float f = m.positions[3 * v + std::size_t(a)];
        lo[a] = std::min(lo[a], f), hi[a] = std::max(hi[a], f);
      }
    const std::string nv = std::to_string(vertices), ni = std::to_string(indexCount);
    // Accessor i reads buffer view i: positions, [normals], [colours], indices.
    const int colorView = hasNormals ? 2 : 1;
    const int indexView = colorView + (hasColors ? 1 : 0);
    json += R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"name":"solid"}],)";
    json += R"("meshes":[{"name":"solid","primitives":[{"attributes":{"POSITION":0)";
    if (hasNormals) json += R"(,"NORMAL":1)";
    if (hasColors) json += R"(,"COLOR_0":)" + std::to_string(colorView);
    json += R"(},"indices":)" + std::to_string(indexView) + R"(,"mode":4}]}],)";
    json += R"("accessors":[{"bufferView":0,"componentType":)" + std::to_string(kFloat) + R"(,"count":)" + nv +
            R"(,"type":"VEC3","min":)" + vec3(lo) + R"(,"max":)" + vec3(hi) + "}";
    if (hasNormals)
      json += R"(,{"bufferView":1,"componentType":)" + std::to_string(kFloat) +
              R"(,"count":)" + nv + R"(,"type":"VEC3"})";
    if (hasColors)
      json += R"(,{"bufferView":)" + std::to_string(colorView) + R"(,"componentType":)" + std::to_string(kFloat) +
              R"(,"count":)" + nv + R"(,"type":"VEC3"})";
    json += R"(,{"bufferView":)" + std::to_string(indexView) + R"(,"componentType":)" + std::to_string(kUnsignedInt) +
            R"(,"count":)" + ni + R"(,"type":"SCALAR"}],)";
    json += R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" + std::to_string(positionBytes) +
            R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    if (hasNormals)
      json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes) + R"(,"byteLength":)" +
              std::to_string(normalBytes) + R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    if (hasColors)
      json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes + normalBytes) + R"(,"byteLength":)" +
              std::to_string(colorBytes) + R"(,"target":)" + std::to_string(kArrayBuffer) + "}";
    json += R"(,{"buffer":0,"byteOffset":)" + std::to_string(positionBytes + normalBytes + colorBytes) +
            R"(,"byteLength":)" +
            std::to_string(indexBytes) + R"(,"target":)" + std::to_string(kElementArrayBuffer) + "}],";
    json += R"("buffers":[{"byteLength":)" + std::to_string(binBytes) + "}]}";
  }
  while (json.size() % 4) json += ' ';

  const bool hasBin = binBytes > 0 && indexCount > 0;
  const std::size_t total = 12 + 8 + json.size() + (hasBin ? 8 + binBytes : 0);
  std::vector<std::uint8_t> out;
  out.reserve(total);
  le::append32(out, kGlbMagic);
  le::append32(out, 2);
  le::append32(out, std::uint32_t(total));
  le::append32(out, std::uint32_t(json.size()));
  le::append32(out, kJsonChunk);
  out.insert(out.end(), json.begin(), json.end());
  if (hasBin) {
    le::append32(out, std::uint32_t(binBytes));
    le::append32(out, kBinChunk);
    for (const float f : m.positions) le::appendF32(out, f);
    if (hasNormals)
      for (const float f : unitNormals(m)) le::appendF32(out, f);
    if (hasColors)
      for (const std::uint8_t c : m.colors) le::appendF32(out, srgbToLinear(c));
    for (const std::uint32_t i : m.indices) le::append32(out, i);
  }
  return out;
}

namespace {

using mesh_reading::formatError;

// --- a JSON document, as much as glTF needs ---------------------------------------------------

struct JsonValue {
  enum Kind { Null, Bool, Number, String, Array, Object } kind = Null;
  double number = 0;
  std::string text;
  std::vector<JsonValue> items;                           // Array
  // Object: keys[i] names values[i] (two vectors: a pair holding the incomplete JsonValue does
  // not compile with clang and libstdc++ 12).
  std::vector<std::string> keys;
  std::vector<JsonValue> values;

  const JsonValue* get(std::string_view key) const {
    if (kind != Object) return nullptr;
    for (std::size_t i = 0; i < keys.size(); ++i)
      if (keys[i] == key) return &values[i];
    return nullptr;
  }
};

// Strict JSON (RFC 8259) over the chunk's bytes; nesting is bounded so that a hostile document
// cannot exhaust the stack.
class JsonParser {
 public:
  explicit JsonParser(std::string_view s) : s_(s) {}

  JsonValue document() {
    JsonValue v = value(0);
    space();
    if (at_ != s_.size()) fail("text after the document");
    return v;
  }

 private:
  static constexpr int kMaxDepth = 64;

  [[noreturn]] void fail(const std::string& what) const {
    formatError("glTF JSON at byte " + std::to_string(at_) + ": " + what);
  }
  void space() {
    while (at_ < s_.size() && (s_[at_] == ' ' || s_[at_] == '\t' || s_[at_] == '\n' || s_[at_] == '\r')) ++at_;
  }
  bool take(char c) {
    space();
    if (at_ < s_.size() && s_[at_] == c) return ++at_, true;
    return false;
  }
  void expect(char c) {
    if (!take(c)) fail(std::string("expected '") + c + "'");
  }
  JsonValue value(int depth) {
    if (depth > kMaxDepth) fail("nested too deeply");
    space();
    if (at_ >= s_.size()) fail("unexpected end");
    JsonValue v;
    const char c = s_[at_];
    if (c == '{') {
      ++at_;
      v.kind = JsonValue::Object;
      if (take('}')) return v;
      do {
        space();
        std::string key = string();
        expect(':');
        v.keys.push_back(std::move(key));
        v.values.push_back(value(depth + 1));
      } while (take(','));
      expect('}');
    } else if (c == '[') {
      ++at_;
      v.kind = JsonValue::Array;
      if (take(']')) return v;
      do v.items.push_back(value(depth + 1));
      while (take(','));
      expect(']');
    } else if (c == '"') {
      v.kind = JsonValue::String;
      v.text = string();
    } else if (word("true")) {
      v.kind = JsonValue::Bool;
      v.number = 1;
    } else if (word("false")) {
      v.kind = JsonValue::Bool;
    } else if (word("null")) {
      v.kind = JsonValue::Null;
    } else {
      v.kind = JsonValue::Number;
      const std::size_t from = at_;
      while (at_ < s_.size() && (std::isdigit(static_cast<unsigned char>(s_[at_])) || s_[at_] == '-' || s_[at_] == '+' ||
                                 s_[at_] == '.' || s_[at_] == 'e' || s_[at_] == 'E'))
        ++at_;
      const auto r = std::from_chars(s_.data() + from, s_.data() + at_, v.number);
      if (from == at_ || r.ec != std::errc() || r.ptr != s_.data() + at_) fail("bad value");
    }
    return v;
  }
  bool word(std::string_view w) {
    if (s_.substr(at_, w.size()) != w) return false;
    at_ += w.size();
    return true;
  }
  std::string string() {
    if (at_ >= s_.size() || s_[at_] != '"') fail("expected a string");
    ++at_;
    std::string out;
    while (true) {
      if (at_ >= s_.size()) fail("unterminated string");
      const char c = s_[at_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in a string");
      if (c != '\\') {
        out += c;
        continue;
      }
      if (at_ >= s_.size()) fail("unterminated string");
      const char e = s_[at_++];
      switch (e) {
        case '"': case '\\': case '/': out += e; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          // Names glTF looks up are ASCII: any other code point stands in as '?'.
          unsigned cp = 0;
          const auto r = std::from_chars(s_.data() + at_, s_.data() + std::min(s_.size(), at_ + 4), cp, 16);
          if (r.ptr != s_.data() + at_ + 4) fail("bad \\u escape");
          at_ += 4;
          out += cp < 0x80 ? char(cp) : '?';
          break;
        }
        default:
          fail("bad escape");
      }
    }
  }

  std::string_view s_;
  std::size_t at_ = 0;
};

// --- glTF accessors over the binary chunk -----------------------------------------------------

// A non-negative integer member (absent: `fallback`, or an error when there is none).
std::uint64_t count(const JsonValue& obj, std::string_view key, std::optional<std::uint64_t> fallback = std::nullopt) {
  const JsonValue* v = obj.get(key);
  if (!v) {
    if (!fallback) formatError("glTF: \"" + std::string(key) + "\" is missing");
    return *fallback;
  }
  if (v->kind != JsonValue::Number || !(v->number >= 0) || v->number > 9007199254740992.0 ||
      v->number != std::floor(v->number))
    formatError("glTF: \"" + std::string(key) + "\" is not a non-negative integer");
  return std::uint64_t(v->number);
}

const JsonValue& element(const JsonValue& root, std::string_view array, std::uint64_t i) {
  const JsonValue* a = root.get(array);
  if (!a || a->kind != JsonValue::Array || i >= a->items.size())
    formatError("glTF: " + std::string(array) + " " + std::to_string(i) + " does not exist");
  return a->items[std::size_t(i)];
}

// An accessor's elements in the binary chunk, every byte checked to lie inside it.
struct Accessor {
  const std::uint8_t* data = nullptr;
  std::size_t count = 0, stride = 0, components = 0, componentSize = 0;
  int componentType = 0;
  bool normalized = false;

  // Component c of element i, as the file stores it (normalized integers divided out).
  double get(std::size_t i, std::size_t c) const {
    const std::uint8_t* p = data + i * stride + c * componentSize;
    switch (componentType) {
      case 5120: return normalized ? std::max(std::int8_t(*p) / 127.0, -1.0) : double(std::int8_t(*p));
      case 5121: return normalized ? *p / 255.0 : double(*p);
      case 5122: return normalized ? std::max(std::int16_t(le::get16(p)) / 32767.0, -1.0) : double(std::int16_t(le::get16(p)));
      case 5123: return normalized ? le::get16(p) / 65535.0 : double(le::get16(p));
      case 5125: return double(le::get32(p));
      default: return double(le::getF32(p));
    }
  }
};

Accessor accessor(const JsonValue& root, std::uint64_t index, std::span<const std::uint8_t> bin) {
  const JsonValue& a = element(root, "accessors", index);
  const std::string which = "glTF accessor " + std::to_string(index);
  if (a.get("sparse")) formatError(which + ": sparse accessors are not read");
  const JsonValue* type = a.get("type");
  const std::string t = type && type->kind == JsonValue::String ? type->text : "";
  Accessor r;
  r.components = t == "SCALAR" ? 1 : t == "VEC2" ? 2 : t == "VEC3" ? 3 : t == "VEC4" ? 4 : 0;
  if (!r.components) formatError(which + ": type \"" + t.substr(0, 20) + "\" is not read");
  r.componentType = int(count(a, "componentType"));
  r.componentSize = r.componentType == 5120 || r.componentType == 5121   ? 1
                    : r.componentType == 5122 || r.componentType == 5123 ? 2
                    : r.componentType == 5125 || r.componentType == 5126 ? 4
                                                                         : 0;
  if (!r.componentSize) formatError(which + ": componentType " + std::to_string(r.componentType) + " is not glTF's");
  const JsonValue* norm = a.get("normalized");
  r.normalized = norm && norm->kind == JsonValue::Bool && norm->number != 0;
  r.count = std::size_t(std::min<std::uint64_t>(count(a, "count"), bin.size() + 1));
  if (!a.get("bufferView")) formatError(which + ": accessors without a bufferView are not read");
  const JsonValue& view = element(root, "bufferViews", count(a, "bufferView"));
  if (count(view, "buffer") != 0) formatError(which + ": only the .glb's own buffer (0) is read");
  const std::uint64_t viewOffset = count(view, "byteOffset", 0), viewLength = count(view, "byteLength");
  const std::uint64_t elementSize = std::uint64_t(r.components) * r.componentSize;
  const std::uint64_t stride = count(view, "byteStride", elementSize);
  const std::uint64_t offset = count(a, "byteOffset", 0);
  if (stride < elementSize || stride > 252) formatError(which + ": byteStride " + std::to_string(stride) + " is not valid");
  if (viewOffset > bin.size() || viewLength > bin.size() - viewOffset)
    formatError(which + ": its bufferView lies outside the binary chunk");
  if (r.count > 0 && (offset > viewLength || (r.count - 1) * stride + elementSize > viewLength - offset))
    formatError(which + ": its " + std::to_string(r.count) + " elements do not fit in its bufferView");
  r.data = bin.data() + viewOffset + offset;
  r.stride = std::size_t(stride);
  return r;
}

}  // namespace

Mesh parseGlb(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 20 || le::get32(bytes.data()) != kGlbMagic) formatError("not a .glb file (no glTF magic number)");
  if (le::get32(bytes.data() + 4) != 2) formatError(".glb version " + std::to_string(le::get32(bytes.data() + 4)) + " is not 2");
  if (le::get32(bytes.data() + 8) > bytes.size()) formatError(".glb is truncated");
  const std::size_t total = le::get32(bytes.data() + 8);
  const std::size_t jsonLength = le::get32(bytes.data() + 12);
  if (le::get32(bytes.data() + 16) != kJsonChunk || jsonLength > total - 20)
    formatError(".glb does not start with a whole JSON chunk");
  std::span<const std::uint8_t> bin;
  const std::size_t binAt = 20 + jsonLength;
  if (total - binAt >= 8 && le::get32(bytes.data() + binAt + 4) == kBinChunk) {
    const std::size_t binLength = le::get32(bytes.data() + binAt);
    if (binLength > total - binAt - 8) formatError(".glb's binary chunk is truncated");
    bin = bytes.subspan(binAt + 8, binLength);
  }
  const JsonValue root =
      JsonParser(std::string_view(reinterpret_cast<const char*>(bytes.data() + 20), jsonLength)).document();
  if (root.kind != JsonValue::Object) formatError("glTF JSON is not an object");
  if (const JsonValue* buffers = root.get("buffers"); buffers && buffers->kind == JsonValue::Array && !buffers->items.empty()) {
    const JsonValue& b0 = buffers->items[0];
    if (b0.get("uri")) formatError("glTF buffer 0 is an external file: only a .glb's own binary chunk is read");
    if (count(b0, "byteLength") > bin.size()) formatError("glTF buffer 0 is longer than the binary chunk");
  }

  Mesh m;
  bool colored = true;
  // Every byte read counts against the binary chunk's length, so a document cannot make a small
  // file read one large accessor again and again: vertices shared by several primitives (one
  // POSITION accessor) are read once, with the first one's COLOR_0.
  std::uint64_t budget = bin.size();
  auto use = [&](const Accessor& a) {
    const std::uint64_t read = std::uint64_t(a.count) * a.components * a.componentSize;
    if (read > budget) formatError("glTF accessors read more bytes than the binary chunk holds");
    budget -= read;
  };
  std::map<std::uint64_t, std::pair<std::uint32_t, std::size_t>> vertexRanges;  // POSITION -> first vertex, count
  const JsonValue* meshes = root.get("meshes");
  if (!meshes || meshes->kind != JsonValue::Array || meshes->items.empty()) formatError("glTF has no meshes");
  for (const JsonValue& mesh : meshes->items) {
    const JsonValue* primitives = mesh.get("primitives");
    if (!primitives || primitives->kind != JsonValue::Array) formatError("glTF mesh without primitives");
    for (const JsonValue& prim : primitives->items) {
      const std::uint64_t mode = count(prim, "mode", 4);
      if (mode != 4) formatError("glTF primitive of mode " + std::to_string(mode) + ": only triangles (4) are read");
      const JsonValue* attributes = prim.get("attributes");
      if (!attributes || attributes->kind != JsonValue::Object) formatError("glTF primitive without attributes");
      const std::uint64_t position = count(*attributes, "POSITION");
      auto range = vertexRanges.find(position);
      if (range == vertexRanges.end()) {
        const Accessor pos = accessor(root, position, bin);
        if (pos.componentType != 5126 || pos.components != 3) formatError("glTF POSITION must be float VEC3");
        use(pos);
        const std::size_t base = m.vertexCount();
        if (base + pos.count > std::numeric_limits<std::uint32_t>::max()) formatError("glTF has more than 2^32 - 1 vertices");
        for (std::size_t v = 0; v < pos.count; ++v)
          for (std::size_t c = 0; c < 3; ++c) {
            const double x = pos.get(v, c);
            if (!std::isfinite(x)) formatError("glTF vertex " + std::to_string(v) + ": coordinate is not finite");
            m.positions.push_back(float(x));
          }
        if (attributes->get("COLOR_0") && colored) {
          const Accessor c = accessor(root, count(*attributes, "COLOR_0"), bin);
          if (c.count != pos.count || c.components < 3 || (c.componentType != 5126 && !c.normalized))
            formatError("glTF COLOR_0 must be float or normalized, VEC3 or VEC4, one per vertex");
          use(c);
          for (std::size_t v = 0; v < c.count; ++v)
            for (std::size_t k = 0; k < 3; ++k) {
              const double x = c.get(v, k);
              if (std::isnan(x)) formatError("glTF vertex " + std::to_string(v) + ": colour is not a number");
              m.colors.push_back(linearToSrgb(x));
            }
        } else {
          colored = false;
        }
        range = vertexRanges.emplace(position, std::pair{std::uint32_t(base), pos.count}).first;
      }
      const auto [base, vertices] = range->second;
      if (prim.get("indices")) {
        const Accessor idx = accessor(root, count(prim, "indices"), bin);
        if (idx.components != 1 || !(idx.componentType == 5121 || idx.componentType == 5123 || idx.componentType == 5125) ||
            idx.normalized)
          formatError("glTF indices must be unsigned integers");
        if (idx.count % 3) formatError("glTF triangle indices do not come in threes");
        use(idx);
        mesh_reading::checkTriangleCount(m.triangleCount() + idx.count / 3);
        for (std::size_t i = 0; i < idx.count; ++i) {
          const double x = idx.get(i, 0);
          if (x >= double(vertices)) formatError("glTF index " + std::to_string(std::uint64_t(x)) + " out of range");
          m.indices.push_back(base + std::uint32_t(x));
        }
      } else {
        if (vertices % 3) formatError("glTF triangle vertices do not come in threes");
        mesh_reading::checkTriangleCount(m.triangleCount() + vertices / 3);
        for (std::size_t i = 0; i < vertices; ++i) m.indices.push_back(base + std::uint32_t(i));
      }
    }
  }
  if (m.indices.empty()) formatError("glTF has no triangles");
  if (!colored) m.colors.clear();
  return m;
}

}  // namespace marzipan
