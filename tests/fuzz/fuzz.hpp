// Shared by the libFuzzer targets of tests/fuzz: each target feeds one decoder of untrusted
// bytes and checks what the decoder's header promises about every input.
//
// Conventions: a target returns 0 for any input the decoder refuses the documented way (its
// own error type) or accepts; anything else is a finding and must abort, so that libFuzzer
// keeps the input: a crash, a sanitizer report, an exception of another type (std::terminate),
// an allocation over -malloc_limit_mb, or a broken invariant (expect below).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace marzipan::fuzz {

// The bound tests/protocol/test_ops.cpp sets on error messages: they must not grow with the
// input, whatever it is.
inline constexpr std::size_t kMaxMessageBytes = 300;

// A promise of the decoder under test; a broken one is a finding like a crash.
inline void expect(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
  std::abort();
}

inline std::span<const std::uint8_t> bytesOf(const std::uint8_t* data, std::size_t size) { return {data, size}; }
inline std::string_view textOf(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// True when `s` can go into a JSON reply as it is (nlohmann refuses to write invalid UTF-8).
inline bool validUtf8(const std::string& s) {
  try {
    (void)nlohmann::json(s).dump();
    return true;
  } catch (const nlohmann::json::type_error&) {
    return false;
  }
}

// An error message fit for a log line or a reply: not empty, short, one line, valid UTF-8.
inline void expectMessage(const std::string& message) {
  expect(!message.empty(), "an error message is not empty");
  expect(message.size() < kMaxMessageBytes, "an error message stays short whatever the input");
  expect(message.find('\n') == std::string::npos, "an error message is one line");
  expect(validUtf8(message), "an error message is valid UTF-8");
}

}  // namespace marzipan::fuzz
