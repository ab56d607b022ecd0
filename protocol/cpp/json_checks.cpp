// The checks of json_checks.hpp.
#include "json_checks.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

namespace marzipan::protocol::checks {

// Text from the request, cut to a readable length at a UTF-8 character boundary: messages
// must not grow with the input, and must stay valid UTF-8 for a JSON-RPC reply.
std::string excerpt(std::string_view s, std::size_t maxChars) {
  if (s.size() <= maxChars) return std::string(s);
  std::size_t cut = maxChars;
  while (cut > 0 && (static_cast<unsigned char>(s[cut]) & 0xC0) == 0x80) --cut;
  std::string out(s.substr(0, cut));
  out.append("...");
  return out;
}

// Quoted and escaped as a JSON string, so that control characters cannot garble a log line.
// Bounded as quoted, not as given: a control character quotes as six bytes (\u0001), so forty
// of them once made a message longer than a message may be (found by fuzz_rpc).
std::string inQuotes(std::string_view s) {
  constexpr std::size_t kMaxQuotedBytes = 48;
  for (std::size_t chars = 40;; chars /= 2) {
    std::string q = json(excerpt(s, chars)).dump(-1, ' ', false, json::error_handler_t::replace);
    if (q.size() <= kMaxQuotedBytes || chars <= 4) return q;
  }
}

std::string elementName(std::string_view key, std::size_t i) { return inQuotes(key) + "[" + std::to_string(i) + "]"; }

std::string formatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// What a value is, for "got ..." in messages; numbers say which.
std::string describe(const json& v) {
  if (v.is_number_float()) return "the number " + formatNumber(v.get<double>());
  if (v.is_number()) return "the integer " + v.dump();
  if (v.is_string()) return "the string " + inQuotes(v.get_ref<const std::string&>());
  return std::string(v.type_name());
}

[[noreturn]] void fail(std::string_view key, const std::string& what) {
  throw OpError(std::string(key), inQuotes(key) + " " + what);
}

std::string listNames(std::span<const std::string_view> names) {
  std::string out;
  for (std::string_view n : names) out += (out.empty() ? "" : ", ") + std::string(n);
  return out;
}

// Refuses any key outside `allowed`; `context` says for which tool, so that a key that is
// valid elsewhere ("shape" on a brush) is explained rather than just called unknown.
void checkKeys(const json& obj, std::span<const std::string_view> allowed, const std::string& context) {
  for (const auto& item : obj.items()) {
    bool known = false;
    for (std::string_view a : allowed) known = known || item.key() == a;
    if (known) continue;
    std::string list;
    for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    throw OpError(excerpt(item.key()), "unknown key " + inQuotes(item.key()) + " for " + context + " (allowed: " + list + ")");
  }
}

const json* find(const json& obj, std::string_view key) {
  const auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

const json& require(const json& obj, std::string_view key, const std::string& context) {
  const json* v = find(obj, key);
  if (!v) fail(key, "is missing (required for " + context + ")");
  return *v;
}

std::string stringValue(const json& v, std::string_view key) {
  if (!v.is_string()) fail(key, "must be a string, got " + describe(v));
  return v.get<std::string>();
}

double finiteNumber(const json& v, std::string_view key) {
  if (!v.is_number()) fail(key, "must be a number, got " + describe(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(key, "must be a finite number");
  return d;
}

double numberInRange(const json& v, std::string_view key, double lo, double hi) {
  const double d = finiteNumber(v, key);
  if (d < lo || d > hi)
    fail(key, "must be between " + formatNumber(lo) + " and " + formatNumber(hi) + ", got " + formatNumber(d));
  return d;
}

bool booleanValue(const json& v, std::string_view key) {
  if (!v.is_boolean()) fail(key, "must be true or false, got " + describe(v));
  return v.get<bool>();
}

std::int64_t integerInRange(const json& v, std::string_view key, std::int64_t lo, std::int64_t hi) {
  if (!v.is_number_integer()) fail(key, "must be an integer, got " + describe(v));
  // Unsigned and signed integers are stored apart; compare each without narrowing first.
  const bool inRange = v.is_number_unsigned() ? hi >= 0 && v.get<std::uint64_t>() <= std::uint64_t(hi) &&
                                                    std::int64_t(v.get<std::uint64_t>()) >= lo
                                              : v.get<std::int64_t>() >= lo && v.get<std::int64_t>() <= hi;
  if (!inRange) fail(key, "must be between " + std::to_string(lo) + " and " + std::to_string(hi) + ", got " + v.dump());
  return v.get<std::int64_t>();
}

Vec3 vec3Value(const json& v, std::string_view key, double bound) {
  if (!v.is_array() || v.size() != 3)
    fail(key, "must be an array of three numbers [x, y, z], got " +
                  (v.is_array() ? "an array of " + std::to_string(v.size()) : describe(v)));
  Vec3 c;
  for (int a = 0; a < 3; ++a) {
    const json& x = v[std::size_t(a)];
    // Written only for an error: a dab's centre is read three numbers a dab.
    const auto element = [&] { return elementName(key, std::size_t(a)); };
    if (!x.is_number()) throw OpError(std::string(key), element() + " must be a number, got " + describe(x));
    c[a] = x.get<double>();
    if (!std::isfinite(c[a])) throw OpError(std::string(key), element() + " must be a finite number");
    if (std::abs(c[a]) > bound)
      throw OpError(std::string(key), element() + " must be within +-" + formatNumber(bound) + " vu, got " +
                                          formatNumber(c[a]));
  }
  return c;
}

double numberParam(const json& obj, const NumberParam& p, const std::string& context, double radius) {
  const json* v = find(obj, p.key);
  if (!v) {
    if (!p.defaultValue) fail(p.key, "is missing (required for " + context + ")");
    return *p.defaultValue;
  }
  const double d = finiteNumber(*v, p.key);
  const double most = p.maxPerRadius > 0 ? std::min(p.maximum, p.maxPerRadius * radius) : p.maximum;
  const bool aboveLow = p.exclusiveMinimum ? d > p.minimum : d >= p.minimum;
  const bool belowHigh = p.exclusiveMaximum ? d < most : d <= most;
  if (aboveLow && belowHigh) return d;
  std::string range = p.exclusiveMinimum || p.exclusiveMaximum
                          ? std::string("in ") + (p.exclusiveMinimum ? "(" : "[") + formatNumber(p.minimum) + ", " +
                                formatNumber(most) + (p.exclusiveMaximum ? ")" : "]")
                          : "between " + formatNumber(p.minimum) + " and " + formatNumber(most);
  if (p.maxPerRadius > 0) {
    const std::string share = p.maxPerRadius == 0.5 ? "half the radius"
                              : p.maxPerRadius == 1 ? "the radius"
                                                    : formatNumber(p.maxPerRadius) + " times the radius";
    range += " (at most " + share + ", at most " + formatNumber(p.maximum) + ")";
  }
  fail(p.key, "must be " + range + ", got " + formatNumber(d));
}

std::int64_t integerParam(const json& obj, const IntegerParam& p, const std::string& context) {
  const json* v = find(obj, p.key);
  if (!v) {
    if (!p.defaultValue) fail(p.key, "is missing (required for " + context + ")");
    return *p.defaultValue;
  }
  return integerInRange(*v, p.key, p.minimum, p.maximum);
}

Vec3 pointParam(const json& obj, const PointParam& p, const std::string& context) {
  return vec3Value(require(obj, p.key, context), p.key, p.bound);
}

std::optional<Vec3> vectorParam(const json& obj, const VectorParam& p) {
  const json* v = find(obj, p.key);
  if (!v) return std::nullopt;
  const Vec3 d = vec3Value(*v, p.key, std::numeric_limits<double>::max());
  if (d == Vec3{0, 0, 0}) fail(p.key, "must not be [0, 0, 0] (a direction)");
  return d;
}

std::size_t enumParam(const json& obj, const EnumParam& p, const std::string& context) {
  const json* v = find(obj, p.key);
  const std::string name = v ? stringValue(*v, p.key) : p.defaultValue ? std::string(*p.defaultValue) : std::string();
  if (!v && !p.defaultValue) fail(p.key, "is missing (required for " + context + ")");
  for (std::size_t i = 0; i < p.values.size(); ++i)
    if (p.values[i] == name) return i;
  fail(p.key, "must be one of " + listNames(p.values) + ", got " + inQuotes(name));
}

bool booleanParam(const json& obj, const BooleanParam& p) {
  const json* v = find(obj, p.key);
  return v ? booleanValue(*v, p.key) : p.defaultValue;
}

SrgbColor colorValue(const json& v, std::string_view key) {
  if (!v.is_array() || v.size() != 3)
    fail(key, "must be a colour [r, g, b] of three integers 0..255, got " +
                  (v.is_array() ? "an array of " + std::to_string(v.size()) : describe(v)));
  std::uint8_t c[3];
  for (std::size_t a = 0; a < 3; ++a) {
    const json& x = v[a];
    const bool ok = x.is_number_unsigned() ? x.get<std::uint64_t>() <= 255
                    : x.is_number_integer()  ? x.get<std::int64_t>() >= 0 && x.get<std::int64_t>() <= 255
                                             : false;
    if (!ok)
      throw OpError(std::string(key), elementName(key, a) + " must be an integer from 0 to 255, got " +
                                          describe(x));
    c[a] = std::uint8_t(x.get<std::uint64_t>());
  }
  return {c[0], c[1], c[2]};
}

std::optional<SrgbColor> colorParam(const json& obj, const ColorParam& p, const std::string& context) {
  const json* v = find(obj, p.key);
  if (!v) {
    if (!p.optional) fail(p.key, "is missing (required for " + context + ")");
    return std::nullopt;
  }
  return colorValue(*v, p.key);
}

namespace {

// What nlohmann may append after the token it quotes: "; expected " and a token type name.
constexpr std::string_view kExpected = "; expected ";
constexpr std::string_view kTokenTypeNames[] = {
    "true literal", "false literal", "null literal", "string literal", "number literal", "'['", "'{'", "']'", "'}'",
    "':'", "','", "<parse error>", "end of input", "'[', '{', or a literal", "<uninitialized>", "unknown token"};

// The parser's error text for a user: without its bracketed exception id, and with the input
// token it quotes ("last read: '...'", "number overflow parsing '...'") cut and escaped like any
// other quoted input, since that token is as long as the input makes it and need not be UTF-8.
std::string jsonErrorText(const std::string& what) {
  const auto close = what.find("] ");
  const std::string text = close != std::string::npos && !what.empty() && what.front() == '[' ? what.substr(close + 2) : what;
  for (const std::string_view open : {"last read: '", "parsing '"}) {
    const std::size_t at = text.find(open);
    if (at == std::string::npos) continue;
    std::string_view token = std::string_view(text).substr(at + open.size());
    std::string_view tail;
    const std::size_t expected = token.rfind(kExpected);
    if (expected != std::string_view::npos && expected > 0 && token[expected - 1] == '\'') {
      const std::string_view name = token.substr(expected + kExpected.size());
      for (const std::string_view known : kTokenTypeNames)
        if (name == known) tail = token.substr(expected), token = token.substr(0, expected - 1);
    }
    if (tail.empty() && !token.empty() && token.back() == '\'') token.remove_suffix(1);
    return text.substr(0, at + open.size() - 1) + inQuotes(token) + std::string(tail);
  }
  return text;
}
}  // namespace

namespace {

// nlohmann's SAX events built into a value as its own DOM parser builds it, refusing a level past
// kMaxJsonDepth as it opens (the parser itself does not recurse, but copying, comparing or
// writing a value does, once per level: a 1 MiB frame of brackets would overflow the stack) and
// noting the first key an object repeats. The object being built is where its keys are looked
// up: with the callback parser this replaces, which kept a set of each object's keys beside it,
// parseJsonText took 53.8K instructions a dab_message message, 39.5K since
// (docs/benchmark-log.md, capacity, 2026-11-30).
class CheckedDom {
 public:
  explicit CheckedDom(json& root) : root_(root) {}
  std::optional<std::string> duplicate;  // the first key an object repeated ("" is a key too)

  bool null() { return put(nullptr); }
  bool boolean(bool v) { return put(v); }
  bool number_integer(json::number_integer_t v) { return put(v); }
  bool number_unsigned(json::number_unsigned_t v) { return put(v); }
  bool number_float(json::number_float_t v, const json::string_t&) { return put(v); }
  bool string(json::string_t& v) { return put(v); }
  bool binary(json::binary_t& v) { return put(std::move(v)); }
  bool start_object(std::size_t) { return open(json::value_t::object); }
  bool start_array(std::size_t) { return open(json::value_t::array); }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool key(json::string_t& k) {
    // A repeated key's later value replaces the earlier, as in nlohmann's own parser.
    const auto [at, added] = open_.back()->get_ref<json::object_t&>().try_emplace(k);
    if (!added && !duplicate) duplicate = k;
    element_ = &at->second;
    return true;
  }
  template <class Exception>
  bool parse_error(std::size_t, const std::string&, const Exception& e) {
    throw e;
  }

 private:
  json* place() {
    if (open_.empty()) return &root_;
    json& top = *open_.back();
    if (top.is_array()) return &top.get_ref<json::array_t&>().emplace_back();
    return element_;
  }
  template <class V>
  bool put(V&& v) {
    *place() = json(std::forward<V>(v));
    return true;
  }
  bool open(json::value_t kind) {
    if (open_.size() >= std::size_t(kMaxJsonDepth))
      throw OpError("", "not valid JSON: nested deeper than " + std::to_string(kMaxJsonDepth) + " arrays and objects");
    json* v = place();
    *v = json(kind);
    open_.push_back(v);
    return true;
  }
  bool close() {
    open_.pop_back();
    return true;
  }
  json& root_;
  std::vector<json*> open_;  // the arrays and objects being read, outermost first
  json* element_ = nullptr;  // the member the last key named
};

}  // namespace

json parseJsonText(std::string_view text) {
  json value;
  CheckedDom dom(value);
  try {
    json::sax_parse(text.begin(), text.end(), &dom);
  } catch (const json::exception& e) {
    throw OpError("", "not valid JSON: " + jsonErrorText(e.what()));
  }
  if (dom.duplicate)
    throw OpError(excerpt(*dom.duplicate), "key " + inQuotes(*dom.duplicate) + " appears more than once");
  return value;
}

}  // namespace marzipan::protocol::checks
