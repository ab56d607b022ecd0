#include "mesh_reading.hpp"

#include <charconv>
#include <cmath>

#include "errors.hpp"
#include "mesh_format.hpp"

namespace marzipan::mesh_reading {

void formatError(const std::string& what) { throw EngineError(ErrorKind::Format, "mesh", what); }

void lineError(std::size_t line, const std::string& what) { formatError("line " + std::to_string(line) + ": " + what); }

void checkTriangleCount(std::size_t n) {
  if (n > kMaxMeshTriangles) formatError("more than " + std::to_string(kMaxMeshTriangles) + " triangles");
}

std::string_view token(std::string_view& s) {
  std::size_t i = 0;
  while (i < s.size() && isSpace(s[i])) ++i;
  std::size_t j = i;
  while (j < s.size() && !isSpace(s[j])) ++j;
  const std::string_view t = s.substr(i, j - i);
  s.remove_prefix(j);
  return t;
}

bool parseFloat(std::string_view t, float& out) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  const auto r = std::from_chars(t.data(), t.data() + t.size(), out);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

float coordinate(std::string_view t, std::size_t line) {
  float f;
  if (!parseFloat(t, f)) lineError(line, "expected a number, got \"" + std::string(t.substr(0, 40)) + "\"");
  if (!std::isfinite(f)) lineError(line, "coordinate is not finite");
  return f;
}

}  // namespace marzipan::mesh_reading
