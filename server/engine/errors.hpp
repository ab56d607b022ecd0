// The engine's one error type. Every public entry point validates its parameters before it
// touches a volume, so a thrown EngineError always means "nothing changed".
#pragma once

#include <stdexcept>
#include <string>

namespace marzipan {

enum class ErrorKind {
  InvalidArgument,  // NaN, infinite, negative or otherwise meaningless parameter
  OutOfDomain,      // a position or region that does not meet the volume's domain
  TooLarge,         // a size over the engine's limits
  Format,           // a file or buffer that cannot be decoded
};

class EngineError : public std::runtime_error {
 public:
  EngineError(ErrorKind kind, std::string field, const std::string& message)
      : std::runtime_error(field.empty() ? message : field + ": " + message),
        kind_(kind),
        field_(std::move(field)) {}

  ErrorKind kind() const { return kind_; }
  // The parameter the error is about ("radius", "center"), or empty.
  const std::string& field() const { return field_; }

 private:
  ErrorKind kind_;
  std::string field_;
};

// Precondition helpers: each names the parameter and says what a valid value looks like.
void requireFinite(double v, const char* field);
void requirePositive(double v, const char* field);
void requireRange(double v, double lo, double hi, const char* field);

}  // namespace marzipan
