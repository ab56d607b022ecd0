// The per-address limits' notion of one address (service/client_address.hpp): an IPv6 /64 is
// one address, an IPv4-mapped IPv6 address is its IPv4 one. Issue 31 item 11: the limits keyed
// on the full IPv6 address, so one host with a /64 had 2^64 addresses' worth of them.
#include <catch2/catch.hpp>

#include "../service/hub_support.hpp"
#include "service/client_address.hpp"

using namespace marzipan::service;
using namespace marzipan::service::testing;

TEST_CASE("per-address limits: an IPv6 address counts by its /64, an IPv4-mapped one as IPv4", "[hub][address]") {
  CHECK(addressLimitKey("203.0.113.7") == "203.0.113.7");
  CHECK(addressLimitKey("203.0.113.7:5000") == "203.0.113.7");
  CHECK(addressLimitKey("[2001:db8:1:2:3:4:5:6]:5000") == "2001:db8:1:2::/64");
  CHECK(addressLimitKey("[2001:db8:1:2:ffff:ffff:ffff:ffff]:1") == "2001:db8:1:2::/64");
  CHECK(addressLimitKey("2001:db8:1:2::9") == "2001:db8:1:2::/64");
  CHECK(addressLimitKey("[2001:DB8:1:2::9]:1") == "2001:db8:1:2::/64");  // one spelling per prefix
  CHECK(addressLimitKey("[2001:db8:1:3::9]:1") == "2001:db8:1:3::/64");
  CHECK(addressLimitKey("[fe80::1%eth0]:1") == "fe80::/64");
  CHECK(addressLimitKey("[::1]:8080") == "::/64");
  CHECK(addressLimitKey("[::ffff:203.0.113.7]:5000") == "203.0.113.7");
  CHECK(addressLimitKey("::ffff:cb00:7107") == "203.0.113.7");
  // Not an address (the tests' peers, "?" when the socket had none): itself.
  CHECK(addressLimitKey("test") == "test");
  CHECK(addressLimitKey("?") == "?");
  CHECK(addressLimitKey("[nonsense]:1") == "[nonsense]:1");
}

TEST_CASE("max_creates_per_address_per_minute counts one IPv6 /64 as one address", "[hub][address]") {
  HubOptions o = twoWorkerOptions();
  o.limits.maxCreatesPerAddressPerMinute = 2;
  Hub hub(o);
  const json create = {{"size", {32, 32, 32}}, {"solid", "sphere"}};
  TestClient a(hub, "[2001:db8:1:2::a]:40000"), b(hub, "[2001:db8:1:2:ffff::b]:40001"),
      c(hub, "[2001:db8:1:2:1234:5678:9abc:def0]:40002"), elsewhere(hub, "[2001:db8:1:3::a]:40003");
  a.result("session.create", create);
  b.result("session.create", create);
  const json third = c.call("session.create", create);
  INFO(third.dump());
  CHECK(third["error"]["code"] == -32004);
  CHECK(third["error"]["data"]["limit"] == "max_creates_per_address_per_minute");
  elsewhere.result("session.create", create);

  // A dual-stack server sees IPv4 clients as ::ffff:a.b.c.d: they are IPv4 addresses, each its
  // own, and one with the IPv4 address of a client seen directly.
  TestClient v4(hub, "198.51.100.1:40004"), mapped(hub, "[::ffff:198.51.100.1]:40005"),
      again(hub, "[::ffff:198.51.100.1]:40006"), other(hub, "[::ffff:198.51.100.2]:40007");
  v4.result("session.create", create);
  mapped.result("session.create", create);
  CHECK(again.call("session.create", create)["error"]["data"]["limit"] == "max_creates_per_address_per_minute");
  other.result("session.create", create);
}
