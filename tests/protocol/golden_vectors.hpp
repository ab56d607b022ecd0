// The golden vectors that pin the protocol for every implementation
// (tests/protocol/vectors/vectors.json; marzipan::test_paths::kProtocolVectors),
// read once per test binary.
#pragma once

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>
#include "test_paths.hpp"

namespace marzipan::testing {

inline const nlohmann::json& goldenVectors() {
  static const nlohmann::json v = [] {
    std::ifstream in(marzipan::test_paths::kProtocolVectors, std::ios::binary);
    REQUIRE(in.good());
    std::stringstream text;
    text << in.rdbuf();
    return nlohmann::json::parse(text.str());
  }();
  return v;
}

}  // namespace marzipan::testing
