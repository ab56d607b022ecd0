// The one error type of the engine and of the value checks and codecs it shares with the
// protocol (protocol/cpp/values.hpp, protocol/cpp/splats.hpp). Standard library only. Whatever
// validates before it acts throws it before anything changes, so a thrown EngineError always
// means "nothing changed".
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

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

}  // namespace marzipan
