// The libFuzzer dictionary of the JSON-RPC target (tests/fuzz/dict/rpc.dict) against the
// methods rpc.hpp reads: random mutation rarely spells a method's name, so a method missing
// from the dictionary is one the fuzzer seldom reaches past parseRequest. The registry's tool
// names and keys are checked by protocol/registry/generate.py; the method names live in
// kMethodNames, so they are checked here.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "protocol/cpp/rpc.hpp"
#include "test_paths.hpp"

using namespace marzipan;

TEST_CASE("the rpc fuzz dictionary spells every method", "[rpc][fuzz]") {
  // kProtocolVectors is tests/protocol/vectors/vectors.json.
  const std::filesystem::path dict =
      std::filesystem::path(test_paths::kProtocolVectors).parent_path().parent_path().parent_path() / "fuzz" / "dict" /
      "rpc.dict";
  std::ifstream in(dict);
  REQUIRE(in.good());
  std::set<std::string> entries;
  for (std::string line; std::getline(in, line);) entries.insert(line);
  for (const auto& [method, name] : protocol::kMethodNames) {
    INFO(name);
    CHECK(entries.count("\"\\\"" + std::string(name) + "\\\"\"") == 1);
  }
}
