// Helpers shared by the Session tests (test_session*.cpp, test_surface_tools.cpp): the check that
// a call is refused with a given JSON-RPC code and field.
#pragma once

#include <catch2/catch.hpp>

#include <functional>
#include <string>

#include "protocol/cpp/rpc.hpp"
#include "service/session.hpp"

namespace marzipan::service::testing {

// f() must throw a ServiceError of this code naming this field.
inline void requireError(const std::function<void()>& f, protocol::RpcCode code, const std::string& field) {
  try {
    f();
    FAIL("no ServiceError thrown");
  } catch (const ServiceError& e) {
    INFO(e.what());
    CHECK(e.code() == code);
    CHECK(e.field() == field);
  }
}

}  // namespace marzipan::service::testing
