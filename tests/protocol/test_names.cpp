// Display names (nameValue, protocol/cpp/rpc.hpp; PROTOCOL.md, Presence): what a name that shows
// nothing, or shows the same as another, is made of. Issue 31 item 10 found names made only of
// zero-width, direction or filler characters accepted, and look-alikes ("Ada" + U+200E).
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "golden_vectors.hpp"
#include "protocol/cpp/rpc.hpp"

using namespace marzipan::protocol;
using nlohmann::json;

namespace {

// The field nameValue's refusal names, "" when it accepts.
std::string refusal(const std::string& name) {
  try {
    nameValue(json(name));
    return "";
  } catch (const OpError& e) {
    return e.field();
  }
}

}  // namespace

TEST_CASE("names of invisible characters only are refused", "[rpc][names]") {
  // U+200B-U+200F zero width space, non-joiner, joiner, left-to-right and right-to-left mark;
  // U+2060 word joiner; U+FEFF zero width no-break space; the Hangul fillers U+115F, U+1160,
  // U+3164, U+FFA0; U+2800 the blank braille pattern; U+00AD soft hyphen; U+180E Mongolian
  // vowel separator.
  const std::vector<std::string> blank = {
      "\u200b", "\u200c", "\u200d", "\u200e", "\u200f", "\u2060", "\ufeff", "\u115f", "\u1160", "\u3164", "\uffa0",
      "\u2800", "\u00ad", "\u180e", "\u200b\u200c\u200d", " \u3164 ", "\ufe0f", "\ufe0f\ufe0f", "\u3000\u2002 \u00a0"};
  for (const std::string& name : blank) {
    INFO(json(name).dump(-1, ' ', true));
    CHECK(refusal(name) == "name");
  }
}

TEST_CASE("names that look like another name are refused", "[rpc][names]") {
  for (const std::string& name : std::vector<std::string>{"Ada\u200e", "Ada\u200b", "A\u200dda", "\ufeffAda", "Ada\u3164", "Ad\u00ada",
                                  "\u2060Ada", "Ada\u200f", "Ada\u034f", "Ada\u061c", "Ada\u206a"}) {
    INFO(json(name).dump(-1, ' ', true));
    CHECK(refusal(name) == "name");
  }
  // The existing rules hold: controls, separators and bidi controls anywhere, 64 code points.
  for (const std::string& name : std::vector<std::string>{"a\u0007b", "a\u0085b", "a\u2028b", "a\u202eb", "a\u2067b", std::string(65, 'x')}) {
    INFO(json(name).dump(-1, ' ', true));
    CHECK(refusal(name) == "name");
  }
}

TEST_CASE("visible names are kept, trimmed of white space only", "[rpc][names]") {
  CHECK(nameValue(json("  Ada \u00e9\u00e9  ")) == "Ada \u00e9\u00e9");
  CHECK(nameValue(json("\u3000Ann Lee\u2002")) == "Ann Lee");
  CHECK(nameValue(json("\u202fZo\u00eb\u205f")) == "Zo\u00eb");
  // A variation selector after a visible character is part of it (an emoji's presentation).
  CHECK(nameValue(json("\u2764\ufe0f Ada")) == "\u2764\ufe0f Ada");
  CHECK(nameValue(json("\ud55c\uad6d")) == "\ud55c\uad6d");  // Hangul syllables, not fillers
  CHECK(nameValue(json("\u05e9\u05e8\u05d4")) == "\u05e9\u05e8\u05d4");  // right-to-left letters, no marks
  std::string longest;
  for (int i = 0; i < 64; ++i) longest += "\u00e9";
  CHECK(nameValue(json(longest)) == longest);
}

TEST_CASE("vectors: refused names are refused by session.join and session.create", "[rpc][names]") {
  int names = 0;
  for (const auto& r : marzipan::testing::goldenVectors()["invalid_requests"]) {
    if (r.value("field", "") != "name") continue;
    INFO(r["name"].get<std::string>());
    const json m = json::parse(r["text"].get<std::string>());
    try {
      if (m["method"] == "session.join") parseJoinParams(m["params"]);
      else parseCreateParams(m["params"]);
      FAIL("accepted");
    } catch (const OpError& e) {
      CHECK(e.field() == "name");
    }
    ++names;
  }
  CHECK(names >= 5);
}
