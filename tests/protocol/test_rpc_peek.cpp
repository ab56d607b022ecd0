// peekRequestId (protocol/cpp/rpc.hpp) against parseRequest: the same id and notification flag
// on every valid request (the golden vectors and hand-written ones), nullopt (answer with id
// null) on malformed text, in one pass over texts of max_text_bytes.
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "golden_vectors.hpp"
#include "protocol/cpp/rpc.hpp"

using namespace marzipan::protocol;
using nlohmann::json;

namespace {

const json& vectors() { return marzipan::testing::goldenVectors(); }

// The id and notification flag of parseRequest's answer (its request, or its refusal).
PeekedId parsedId(const std::string& text) {
  const ParsedRequest p = parseRequest(text);
  if (p.request) return {p.request->id.value_or(json(nullptr)), !p.request->id};
  return {p.error->id, p.error->notification};
}

void checkAgrees(const std::string& text) {
  INFO(text.substr(0, 200));
  const PeekedId parsed = parsedId(text);
  const std::optional<PeekedId> peeked = peekRequestId(text);
  REQUIRE(peeked);
  CHECK(peeked->id == parsed.id);
  CHECK(peeked->notification == parsed.notification);
}

// A request with `params` (a JSON text) and the id members `ids` ("" for none), built by hand
// so that the texts may hold what json::dump never writes.
std::string request(const std::string& params, const std::string& ids) {
  return R"({"jsonrpc":"2.0",)" + ids + (ids.empty() ? "" : ",") + R"("method":"session.stats","params":)" + params + "}";
}

}  // namespace

TEST_CASE("peekRequestId finds parseRequest's id in every golden vector", "[rpc]") {
  const auto& v = vectors();
  int requests = 0, notifications = 0;
  // The notifications are the server's (refused by parseRequest as unknown methods, without
  // an answer) and presence.
  for (const char* group : {"requests", "notifications"}) {
    for (const auto& r : v[group]) {
      const std::string text = r["text"];
      if (group == std::string("requests")) REQUIRE(parseRequest(text).request);
      checkAgrees(text);
      (peekRequestId(text)->notification ? notifications : requests) += 1;
      // Every proper prefix of a request is malformed (it ends inside its object).
      for (std::size_t n = 0; n < text.size(); ++n) {
        INFO(text.substr(0, n));
        CHECK_FALSE(peekRequestId(std::string_view(text).substr(0, n)));
      }
    }
  }
  CHECK(requests > 20);
  CHECK(notifications > int(v["notifications"].size()));  // and a stroke.dabs of the requests
  // The refused ones: the same id wherever the text is JSON without repeated keys.
  int agreed = 0;
  for (const auto& r : v["invalid_requests"]) {
    const std::string text = r["text"];
    const std::optional<PeekedId> peeked = peekRequestId(text);
    const PeekedId parsed = parsedId(text);
    INFO(r["name"].get<std::string>());
    if (!peeked) {
      CHECK(parsed.id.is_null());
      CHECK_FALSE(parsed.notification);
    } else if (parseRequest(text).error->code != RpcCode::ParseError) {
      CHECK(peeked->id == parsed.id);
      CHECK(peeked->notification == parsed.notification);
      ++agreed;
    }
  }
  CHECK(agreed > 0);
}

TEST_CASE("peekRequestId reads the top-level id only", "[rpc]") {
  // An "id" inside params (and inside strings) is not the request's.
  const std::string onlyInParams = request(R"({"id":7,"a":[{"id":8}],"s":"\"id\":9"})", "");
  checkAgrees(onlyInParams);
  CHECK(peekRequestId(onlyInParams)->notification);
  const std::string after = request(R"({"id":7,"s":"x\\\"},\"id\":9,\"y"})", R"("id":"a\"b")");
  checkAgrees(after);
  CHECK(peekRequestId(after)->id == "a\"b");
  // Escaped spellings of the key, whitespace everywhere, and a byte order mark.
  checkAgrees(R"({"jsonrpc":"2.0","\u0069d":12,"method":"session.stats"})");
  CHECK(peekRequestId(R"({"jsonrpc":"2.0","\u0069\u0064":12,"method":"session.stats"})")->id == 12);
  checkAgrees(" \t\r\n{ \"id\" : -9007199254740991 ,\"jsonrpc\":\"2.0\", \"method\":\"session.stats\" } \n");
  checkAgrees("\xEF\xBB\xBF{\"id\":3,\"jsonrpc\":\"2.0\",\"method\":\"session.stats\"}");
  CHECK(peekRequestId("\xEF\xBB\xBF{\"id\":3}")->id == 3);
  // Ids parseRequest does not accept: there is an id, it cannot be echoed.
  for (const char* id : {"1.5", "1e3", "null", "true", "[1]", R"({"id":1})", "9007199254740992", "-9007199254740992",
                         "18446744073709551616"}) {
    const std::string text = request("{}", std::string(R"("id":)") + id);
    checkAgrees(text);
    CHECK(peekRequestId(text)->id.is_null());
    CHECK_FALSE(peekRequestId(text)->notification);
  }
  // Refused envelopes still name their id, as parseRequest's refusal does.
  checkAgrees(R"({"jsonrpc":"2.0","id":"k","method":"no.such","params":{},"extra":[1,{"b":null}]})");
  checkAgrees(R"({"jsonrpc":"1.0","id":4})");
  checkAgrees(R"({"id":4})");
  checkAgrees("{}");
  CHECK(peekRequestId("{}")->notification);
  // The JSON reader ends the text at a NUL byte (found by fuzz_rpc): what follows is not read.
  const std::string nulTail = std::string(R"({"jsonrpc":"2.0","id":13,"method":"history.redo","params":{}})") +
                              std::string(4, '\0') + "junk";
  checkAgrees(nulTail);
  CHECK(peekRequestId(nulTail)->id == 13);
}

TEST_CASE("peekRequestId gives up on malformed text and on a repeated top-level id", "[rpc]") {
  const std::string good = request(R"({"a":[1,-0.5e+3,true,false,null,"\u00e9\n"]})", R"("id":1)");
  checkAgrees(good);
  for (const std::string& bad : std::vector<std::string>{
           request("{}", R"("id":1,"id":2)"),        // parseRequest refuses repeated keys
           request("{}", R"("id":1,"\u0069d":1)"),  // the same key, spelled twice
           request("{}", R"("id":01)"), request("{}", R"("id":1.)"), request("{}", R"("id":-)"),
           request("{}", R"("id":1e)"), request("{}", R"("id":tru)"), request("{}", R"("id":"a\x")"),
           request("{}", R"("id":"a\u00g1")"), request("{}", "\"id\":\"a\tb\""), request("{,}", R"("id":1)"),
           request(R"({"a":[1,]})", R"("id":1)"), request(R"({"a":[1 2]})", R"("id":1)"),
           request(R"({"a" 1})", R"("id":1)"), request(R"({"a":1,})", R"("id":1)"), request(R"({"a":1]})", R"("id":1)"),
           request(R"({"a":"\"})", R"("id":1)"), good + "x", good + "{}", "[" + good + "]", R"("id")", "7", "",
           "{\"id\":\"\xFF\"}",  // not UTF-8
       }) {
    INFO(bad);
    CHECK_FALSE(peekRequestId(bad));
    const ParsedRequest p = parseRequest(bad);
    REQUIRE(p.error);
    CHECK(p.error->id.is_null());
    CHECK_FALSE(p.error->notification);
  }
}

TEST_CASE("peekRequestId reads a text of max_text_bytes in one pass and bounds the id it parses", "[rpc]") {
  constexpr std::size_t kMiB = 1 << 20;
  // 64 levels of arrays and objects, the outermost object counting, are read; 65 are not.
  const auto nested = [](std::size_t depth) { return std::string(depth, '[') + std::string(depth, ']'); };
  checkAgrees(request(R"({"a":)" + nested(62) + "}", R"("id":5)"));
  CHECK_FALSE(peekRequestId(request(R"({"a":)" + nested(63) + "}", R"("id":5)")));
  CHECK(parseRequest(request(R"({"a":)" + nested(63) + "}", R"("id":5)")).error->code == RpcCode::ParseError);
  CHECK_FALSE(peekRequestId(request(R"({"a":)" + nested(kMiB / 2) + "}", R"("id":5)")));

  // 1 MiB of small nested arrays, strings with escaped quotes and an "id" in each, the
  // request's id after all of it.
  std::string params = R"({"a":[)";
  while (params.size() < kMiB) params += R"([[1,2.5e-3],{"id":"x\"y","b":[null,true]}],)";
  params += "0]}";
  const std::string big = request(params, R"("id":"after")");
  REQUIRE(big.size() > kMiB);
  checkAgrees(big);
  CHECK(peekRequestId(big)->id == "after");
  const std::string bigNotification = request(params, "");
  checkAgrees(bigNotification);
  CHECK(peekRequestId(bigNotification)->notification);

  // An id over kMaxPeekedIdBytes is not parsed: answered with null (parseRequest would echo it).
  const std::string longest(kMaxPeekedIdBytes - 2, 'i');
  checkAgrees(request("{}", R"("id":")" + longest + "\""));
  const std::optional<PeekedId> tooLong = peekRequestId(request("{}", R"("id":")" + longest + "i\""));
  REQUIRE(tooLong);
  CHECK(tooLong->id.is_null());
  CHECK_FALSE(tooLong->notification);
}
