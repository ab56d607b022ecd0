// service/hub/methods.hpp: the table serves every method of the protocol once, with the access
// rule the protocol implies (edits need the edit token; only create, join and cancel work
// outside a session).
#include <catch2/catch.hpp>

#include <set>

#include "service/hub/methods.hpp"

using namespace marzipan;
using namespace marzipan::service;
using protocol::Method;

TEST_CASE("every protocol method has one row, and the rows follow the protocol's edit rule", "[hub][methods]") {
  std::set<Method> rows;
  for (const MethodEntry& e : methodTable()) {
    INFO(protocol::nameOf(protocol::kMethodNames, e.method));
    CHECK(rows.insert(e.method).second);
    CHECK(e.handle != nullptr);
    CHECK(findMethod(e.method) == &e);
  }
  for (const auto& [method, name] : protocol::kMethodNames) {
    INFO(name);
    const MethodEntry* e = findMethod(method);
    REQUIRE(e != nullptr);
    CHECK((e->access == Access::Editor) == protocol::isEdit(method));
    const bool outside = method == Method::SessionCreate || method == Method::SessionJoin || method == Method::OpCancel;
    CHECK((e->access == Access::Anyone) == outside);
  }
  CHECK(rows.size() == protocol::kMethodNames.size());
}
