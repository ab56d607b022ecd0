// Strict reading of JSON values from untrusted messages, shared by the operation objects
// (ops.cpp) and the JSON-RPC params (rpc.cpp), so that every refusal reads the same way.
//
// Conventions: every check throws OpError(field, message) where `field` is the offending key
// and `message` a whole sentence that quotes it ("\"radius\" must be between 0.5 and 1024, got
// 2000"); text taken from the input is cut to 40 characters and JSON-escaped, so a message
// never grows with the input and is always valid UTF-8.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "protocol/cpp/geometry.hpp"
#include "ops.hpp"

namespace marzipan::protocol::checks {

using nlohmann::json;

std::string excerpt(std::string_view s, std::size_t maxChars = 40);
std::string inQuotes(std::string_view s);
// An array element's name in a message: "key"[i].
std::string elementName(std::string_view key, std::size_t i);
std::string formatNumber(double v);
// What a value is, for "got ..." in messages.
std::string describe(const json& v);

// "a, b, c": the names of a table in ops.hpp.
template <class E, std::size_t N>
std::string listNames(const std::array<NameOf<E>, N>& table) {
  std::string out;
  for (const auto& entry : table) out += (out.empty() ? "" : ", ") + std::string(entry.name);
  return out;
}
std::string listNames(std::span<const std::string_view> names);

[[noreturn]] void fail(std::string_view key, const std::string& what);

// Refuses any key of `obj` outside `allowed`; `context` ("tool \"add_blob\"", "params of
// session.create") explains where.
void checkKeys(const json& obj, std::span<const std::string_view> allowed, const std::string& context);
inline void checkKeys(const json& obj, std::initializer_list<std::string_view> allowed, const std::string& context) {
  checkKeys(obj, std::span(allowed.begin(), allowed.size()), context);
}
const json* find(const json& obj, std::string_view key);
const json& require(const json& obj, std::string_view key, const std::string& context);

std::string stringValue(const json& v, std::string_view key);
double finiteNumber(const json& v, std::string_view key);
double numberInRange(const json& v, std::string_view key, double lo, double hi);
bool booleanValue(const json& v, std::string_view key);
std::int64_t integerInRange(const json& v, std::string_view key, std::int64_t lo, std::int64_t hi);
// An array of three finite numbers, each within +-bound.
Vec3 vec3Value(const json& v, std::string_view key, double bound);

// A registry parameter (tool_spec.hpp) of `obj`: its default when the key is left out, or
// "is missing" when it has none; else a value of its type in its range. `radius` is the tool's,
// for a parameter bounded by it too (maxPerRadius).
double numberParam(const json& obj, const NumberParam& p, const std::string& context, double radius = 0);
std::int64_t integerParam(const json& obj, const IntegerParam& p, const std::string& context);
Vec3 pointParam(const json& obj, const PointParam& p, const std::string& context);
// Absent: nullopt; else three finite numbers, not all zero.
std::optional<Vec3> vectorParam(const json& obj, const VectorParam& p);
// The index of the value in p.values.
std::size_t enumParam(const json& obj, const EnumParam& p, const std::string& context);
// Absent: its default; else a JSON boolean.
bool booleanParam(const json& obj, const BooleanParam& p);
// Absent: nullopt when optional, else "is missing"; else [r, g, b], three integers 0..255.
std::optional<SrgbColor> colorParam(const json& obj, const ColorParam& p, const std::string& context);
// A colour value: [r, g, b], three JSON integers 0..255 (2.0 is refused, as for integers).
SrgbColor colorValue(const json& v, std::string_view key);

// Arrays and objects parseJsonText reads nested (the outermost counts): far more levels than
// any message has (a request's dab ray is 6 deep).
inline constexpr int kMaxJsonDepth = 64;

// One JSON value from text. Throws OpError with an empty field when the text is not exactly
// one JSON value or an object repeats a key (a reader would silently keep only one of them),
// and when arrays and objects nest deeper than 64 levels (values are copied recursively).
json parseJsonText(std::string_view text);

}  // namespace marzipan::protocol::checks
