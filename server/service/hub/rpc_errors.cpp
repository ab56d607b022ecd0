#include "service/hub/rpc_errors.hpp"

#include "engine/errors.hpp"
#include "engine/progress.hpp"
#include "service/key_value.hpp"
#include "service/session.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;

Failure failureOf(std::exception_ptr e, const std::function<void(const std::string&)>& log) {
  try {
    std::rethrow_exception(e);
  } catch (const protocol::RpcException& x) {
    return {x.code(), x.what(), x.data()};
  } catch (const protocol::OpError& x) {
    return {RpcCode::InvalidParams, x.message(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const ServiceError& x) {
    return {x.code(), x.message(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const EngineError& x) {
    return {RpcCode::EngineRefused, x.what(), x.field().empty() ? json(nullptr) : json{{"field", x.field()}}};
  } catch (const KvUnavailable&) {
    // etcd did not answer in time, or this server is between two leases.
    return {RpcCode::Busy, "the coordination store (etcd) did not answer this server in time; retry later",
            {{"retry_after_ms", 1000}}};
  } catch (const Cancelled&) {
    return {RpcCode::Cancelled, "the operation was cancelled (op.cancel or server shutdown); the session is unchanged",
            nullptr};
  } catch (const std::exception& x) {
    if (log) log(std::string("internal error: ") + x.what());
    return {RpcCode::Internal, "internal error; the session is unchanged", nullptr};
  } catch (...) {
    if (log) log("internal error");
    return {RpcCode::Internal, "internal error; the session is unchanged", nullptr};
  }
}

}  // namespace marzipan::service
