// service/hub/secrets.hpp: ids and tokens over the URL-safe alphabet, never beginning with '-'
// or '_', and the constant-time comparison.
#include <catch2/catch.hpp>

#include <cctype>
#include <set>
#include <string>

#include "service/hub/secrets.hpp"

using namespace marzipan::service;

TEST_CASE("random ids hold only URL-safe characters and begin with a letter or digit", "[hub][secrets]") {
  std::set<std::string> seen;
  std::set<char> firsts, others;
  for (int i = 0; i < 2000; ++i) {
    const std::string id = randomText(kSessionIdChars);
    REQUIRE(id.size() == kSessionIdChars);
    REQUIRE(std::isalnum(static_cast<unsigned char>(id.front())));
    for (const char ch : id) REQUIRE((std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_'));
    firsts.insert(id.front());
    others.insert(id.begin() + 1, id.end());
    seen.insert(id);
  }
  CHECK(seen.size() == 2000);
  // Each of 62 first characters is missed by 2000 draws with probability (61/62)^2000 < 1e-14;
  // the other positions use all 64.
  CHECK(firsts.size() == 62);
  CHECK(others.size() == 64);
  CHECK(randomText(kTokenChars).size() == kTokenChars);
}

TEST_CASE("sameSecret accepts only the exact secret", "[hub][secrets]") {
  const std::string secret = "Abc-_09xyz";
  CHECK(sameSecret(secret, "Abc-_09xyz"));
  CHECK_FALSE(sameSecret(secret, "Abc-_09xyZ"));
  CHECK_FALSE(sameSecret(secret, "bc-_09xyz"));
  CHECK_FALSE(sameSecret(secret, "Abc-_09xy"));
  CHECK_FALSE(sameSecret(secret, "Abc-_09xyz0"));
  CHECK_FALSE(sameSecret(secret, ""));
  CHECK(sameSecret("", ""));
  CHECK_FALSE(sameSecret("", "a"));
}
