// What an exception thrown while handling a request becomes on the wire: one funnel for every
// method, so that each error keeps its code (protocol/cpp/errors.hpp) and message.
#pragma once

#include <exception>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "protocol/cpp/rpc.hpp"

namespace marzipan::service {

struct Failure {
  protocol::RpcCode code;
  std::string message;
  nlohmann::json data;  // null, or {"field": ...}, {"limit": ...}, ...
};

// Validation errors (RpcException, protocol::OpError, ServiceError, EngineError) keep their code
// and field; Cancelled is -32016; KvUnavailable (etcd out of reach, or no live lease) is -32005
// with retry_after_ms; anything unexpected is -32000 whose text goes to `log` only.
Failure failureOf(std::exception_ptr e, const std::function<void(const std::string&)>& log);

}  // namespace marzipan::service
