// Fuzz target: operation objects as JSON text (protocol/cpp/ops.hpp, parseOpText), the lines
// of `marzipan batch` and the params of tool.apply. An op that parses must round-trip through
// its canonical form; a refusal is an OpError with a short, valid UTF-8 message.
#include <cstddef>
#include <cstdint>

#include "fuzz.hpp"
#include "protocol/cpp/ops.hpp"

using namespace marzipan::protocol;
using marzipan::fuzz::expect;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const Op op = parseOpText(marzipan::fuzz::textOf(data, size));
    const nlohmann::json canonical = toJson(op);
    expect(parseOp(canonical) == op, "parseOp(toJson(op)) == op");
    expect(parseOpText(canonical.dump()) == op, "the canonical text parses to the same op");
    expect(!opName(op).empty(), "every op has a name");
  } catch (const OpError& e) {
    marzipan::fuzz::expectMessage(e.message());
    expect(e.field().size() < 50, "the field is a key, cut to a readable length");
    expect(marzipan::fuzz::validUtf8(e.field()), "the field is valid UTF-8");
  }
  return 0;
}
