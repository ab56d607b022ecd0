// Helpers shared by the Session tests (test_session*.cpp, test_surface_tools.cpp): the check that
// a call is refused with a given JSON-RPC code and field, and dabs at given centres.
#pragma once

#include <catch2/catch.hpp>

#include <functional>
#include <string>
#include <vector>

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

// One dab per point, each at that centre (no ray, weight 1).
inline std::vector<Dab> centres(const std::vector<Vec3>& points) {
  std::vector<Dab> out;
  for (const Vec3 p : points) out.push_back(Dab{p});
  return out;
}

}  // namespace marzipan::service::testing
