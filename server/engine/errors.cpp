#include "errors.hpp"

#include <cmath>
#include <sstream>

namespace marzipan {

void requireFinite(double v, const char* field) {
  if (!std::isfinite(v)) throw EngineError(ErrorKind::InvalidArgument, field, "must be a finite number");
}

void requirePositive(double v, const char* field) {
  requireFinite(v, field);
  if (!(v > 0)) {
    std::ostringstream s;
    s << "must be greater than 0 (got " << v << ")";
    throw EngineError(ErrorKind::InvalidArgument, field, s.str());
  }
}

void requireRange(double v, double lo, double hi, const char* field) {
  requireFinite(v, field);
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << "must be between " << lo << " and " << hi << " (got " << v << ")";
    throw EngineError(ErrorKind::InvalidArgument, field, s.str());
  }
}

}  // namespace marzipan
