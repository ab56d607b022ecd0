// Binary frame headers (protocol/cpp/frames.cpp) and the golden vectors that pin the protocol
// for every implementation (tests/protocol/vectors/vectors.json, path given by the build as
// marzipan::test_paths::kProtocolVectors): each binary vector decodes to its fields and re-encodes to the
// same bytes, every damaged or truncated frame is refused with the named error, every example
// message is well-formed JSON-RPC, and every example op passes or fails parseOp as recorded.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "golden_vectors.hpp"
#include "protocol/cpp/little_endian.hpp"
#include "protocol/cpp/splats.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/ops.hpp"
#include "test_paths.hpp"

using namespace marzipan;
using namespace marzipan::protocol;
using nlohmann::json;

namespace {

const json& vectors() { return marzipan::testing::goldenVectors(); }

std::vector<std::uint8_t> fromHex(const std::string& hex) {
  REQUIRE(hex.size() % 2 == 0);
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i < hex.size(); i += 2) out.push_back(std::uint8_t(std::stoul(hex.substr(i, 2), nullptr, 16)));
  return out;
}

FrameErrorCode errorOf(std::span<const std::uint8_t> bytes, std::uint64_t maxPayload = kMaxFramePayload) {
  const FrameDecodeResult r = decodeFrameHeader(bytes, maxPayload);
  REQUIRE_FALSE(r);
  REQUIRE(r.error.has_value());
  CHECK_FALSE(r.error->message.empty());
  return r.error->code;
}

// The JSON-RPC checks that do not depend on the method (PROTOCOL.md, "Requests"): the code of
// the error such a text gets at that layer and error.data.field, or 0 when it passes them.
struct EnvelopeVerdict {
  int code = 0;
  std::string field;
};

EnvelopeVerdict checkEnvelope(const std::string& text) {
  json m;
  try {
    m = json::parse(text);
  } catch (const json::parse_error&) {
    return {-32700, ""};
  }
  if (!m.is_object()) return {-32600, ""};
  for (const auto& item : m.items())
    if (item.key() != "jsonrpc" && item.key() != "id" && item.key() != "method" && item.key() != "params")
      return {-32600, ""};
  if (!m.contains("jsonrpc") || m["jsonrpc"] != "2.0") return {-32600, ""};
  if (!m.contains("method") || !m["method"].is_string()) return {-32600, ""};
  if (m.contains("id") && !m["id"].is_string() && !m["id"].is_number_integer()) return {-32600, ""};
  const auto& methods = vectors()["methods"];
  const std::string method = m["method"];
  if (std::find(methods.begin(), methods.end(), method) == methods.end()) return {-32601, ""};
  const auto& binary = vectors()["binary_methods"];
  if (m.contains("id") && std::find(binary.begin(), binary.end(), method) != binary.end()) {
    const json& id = m["id"];
    const bool inRange = id.is_number_unsigned() ? id.get<std::uint64_t>() >= 1 && id.get<std::uint64_t>() <= 0xFFFFFFFFu
                                                 : false;
    if (!inRange) return {-32600, ""};
  }
  if (m.contains("params") && !m["params"].is_object()) return {-32602, "params"};
  return {};
}

// The operation object of a tool.apply or volume.morph request, as the server hands it to parseOp.
json opOf(const json& request) {
  json op = request.value("params", json::object());
  if (request["method"] == "volume.morph") op["op"] = "morph";
  return op;
}

}  // namespace

TEST_CASE("frames: every binary vector decodes to its fields and re-encodes to the same bytes") {
  const auto& all = vectors()["binary"];
  REQUIRE(all.size() >= 9);
  std::set<unsigned> kinds;
  for (const auto& v : all) {
    INFO(v["name"].get<std::string>());
    const std::vector<std::uint8_t> bytes = fromHex(v["hex"]);
    const FrameDecodeResult r = decodeFrameHeader(bytes);
    REQUIRE(r);
    const FrameHeader& h = r.frame->header;
    const json& want = v["header"];
    CHECK(h.version == want["version"].get<unsigned>());
    CHECK(unsigned(h.kind) == want["kind"].get<unsigned>());
    CHECK(frameKindName(h.kind) == want["kind_name"].get<std::string>());
    CHECK(h.requestId == want["request_id"].get<std::uint32_t>());
    CHECK(std::to_string(h.revision) == want["revision"].get<std::string>());
    CHECK(h.payloadLength == want["payload_length"].get<std::uint32_t>());
    const std::vector<std::uint8_t> payload = fromHex(v["payload_hex"]);
    CHECK(std::equal(r.frame->payload.begin(), r.frame->payload.end(), payload.begin(), payload.end()));
    CHECK(encodeFrame(h.kind, h.requestId, h.revision, payload) == bytes);
    // Splat payloads are real buffers of the engine's format.
    if (h.kind == FrameKind::SplatsFull || h.kind == FrameKind::SplatsDelta) CHECK_NOTHROW(decodeSplats(r.frame->payload));
    kinds.insert(unsigned(h.kind));
  }
  CHECK(kinds.size() == 11);
}

TEST_CASE("frames: every invalid binary vector is refused with its error") {
  for (const auto& v : vectors()["binary_invalid"]) {
    INFO(v["name"].get<std::string>());
    const std::vector<std::uint8_t> bytes = fromHex(v["hex"]);
    const std::uint64_t limit = v.value("max_payload", kMaxFramePayload);
    CHECK(frameErrorCodeName(errorOf(bytes, limit)) == v["error"].get<std::string>());
  }
}

TEST_CASE("frames: every truncated prefix of a valid frame is refused") {
  for (const auto& v : vectors()["binary"]) {
    const std::vector<std::uint8_t> bytes = fromHex(v["hex"]);
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      INFO(v["name"].get<std::string>() << ", first " << n << " bytes");
      const FrameErrorCode code = errorOf(std::span(bytes).first(n));
      CHECK(code == (n < kFrameHeaderBytes ? FrameErrorCode::ShortHeader : FrameErrorCode::LengthMismatch));
    }
  }
}

TEST_CASE("frames: encoding writes every field little-endian at its offset") {
  const std::vector<std::uint8_t> payload{1, 2, 3};
  const auto bytes = encodeFrame(FrameKind::MeshPly, 0xA1B2C3D4u, 0x1122334455667788ull, payload);
  const std::vector<std::uint8_t> want{'M',  'Z',  'P',  'N',  1,    0,    7,    0,    0xD4, 0xC3, 0xB2, 0xA1, 0x88, 0x77,
                                       0x66, 0x55, 0x44, 0x33, 0x22, 0x11, 3,    0,    0,    0,    1,    2,    3};
  CHECK(bytes == want);
  const auto r = decodeFrameHeader(bytes, 3);
  REQUIRE(r);
  CHECK(r.frame->header == FrameHeader{1, FrameKind::MeshPly, 0xA1B2C3D4u, 0x1122334455667788ull, 3});
  CHECK(r.frame->payload.data() == bytes.data() + kFrameHeaderBytes);
  CHECK(errorOf(bytes, 2) == FrameErrorCode::TooLarge);
  CHECK_THROWS_AS(encodeFrame(FrameKind(0), 1, 1, payload), std::invalid_argument);
  CHECK_THROWS_AS(encodeFrame(FrameKind(12), 1, 1, payload), std::invalid_argument);
  // In place: the same bytes from a buffer holding the payload after room for the header.
  std::vector<std::uint8_t> room(kFrameHeaderBytes, 0xee);
  room.insert(room.end(), payload.begin(), payload.end());
  CHECK(encodeFrameInPlace(FrameKind::MeshPly, 0xA1B2C3D4u, 0x1122334455667788ull, room) == want);
  CHECK(encodeFrameInPlace(FrameKind::MeshPly, 1, 1, std::vector<std::uint8_t>(kFrameHeaderBytes)) ==
        encodeFrame(FrameKind::MeshPly, 1, 1, {}));
  CHECK_THROWS_AS(encodeFrameInPlace(FrameKind::MeshPly, 1, 1, std::vector<std::uint8_t>(kFrameHeaderBytes - 1)),
                  std::invalid_argument);
  CHECK_THROWS_AS(encodeFrameInPlace(FrameKind(12), 1, 1, room), std::invalid_argument);
}

TEST_CASE("frames: every single-byte change to a header field is caught or decoded as that field") {
  const std::vector<std::uint8_t> payload{9, 8, 7, 6};
  const auto good = encodeFrame(FrameKind::FrameJpeg, 5, 6, payload);
  for (std::size_t i = 0; i < kFrameHeaderBytes; ++i) {
    for (int value : {0x00, 0x01, 0x0A, 0xFF}) {
      auto bytes = good;
      if (bytes[i] == value) continue;
      bytes[i] = std::uint8_t(value);
      INFO("byte " << i << " set to " << value);
      const auto r = decodeFrameHeader(bytes);
      if (i < 4) CHECK(errorOf(bytes) == FrameErrorCode::BadMagic);
      else if (i < 6) CHECK(errorOf(bytes) == FrameErrorCode::BadVersion);
      else if (i < 8) CHECK(r.frame.has_value() == isFrameKind(le::get16(bytes.data() + 6)));
      else if (i < 20) CHECK(r);
      else CHECK(errorOf(bytes) == FrameErrorCode::LengthMismatch);
    }
  }
}

TEST_CASE("vectors: every example message is JSON-RPC 2.0 of a known method") {
  const auto& v = vectors();
  std::set<std::string> requested;
  for (const auto& r : v["requests"]) {
    INFO(r["name"].get<std::string>());
    const EnvelopeVerdict verdict = checkEnvelope(r["text"]);
    CHECK(verdict.code == 0);
    const json m = json::parse(r["text"].get<std::string>());
    CHECK(m["method"] == r["method"]);
    requested.insert(r["method"].get<std::string>());
    if (m["method"] == "tool.apply" && !m["params"].contains("ray")) CHECK_NOTHROW(parseOp(opOf(m)));
    if (m["method"] == "volume.morph") CHECK_NOTHROW(parseOp(opOf(m)));
  }
  CHECK(requested.size() == v["methods"].size());
  for (const auto& r : v["responses"]) {
    INFO(r["name"].get<std::string>());
    const json m = json::parse(r["text"].get<std::string>());
    CHECK(m["jsonrpc"] == "2.0");
    CHECK((m["id"].is_string() || m["id"].is_number_integer()));
    CHECK(m["result"].is_object());
    CHECK_FALSE(m.contains("error"));
  }
  for (const auto& e : v["errors"]) {
    INFO(e["name"].get<std::string>());
    const json m = json::parse(e["text"].get<std::string>());
    CHECK(m["jsonrpc"] == "2.0");
    CHECK(m.contains("id"));
    const int code = m["error"]["code"];
    CHECK(code == e["code"].get<int>());
    CHECK(((code >= -32700 && code <= -32600) || (code >= -32099 && code <= -32000)));
    CHECK_FALSE(m["error"]["message"].get<std::string>().empty());
    CHECK_FALSE(m.contains("result"));
  }
  for (const auto& n : v["notifications"]) {
    INFO(n["name"].get<std::string>());
    const json m = json::parse(n["text"].get<std::string>());
    CHECK(m["jsonrpc"] == "2.0");
    CHECK_FALSE(m.contains("id"));
    CHECK(m["method"] == n["method"]);
    CHECK(m["params"].is_object());
  }
}

TEST_CASE("vectors: invalid requests fail at their layer with their code and field") {
  for (const auto& r : vectors()["invalid_requests"]) {
    INFO(r["name"].get<std::string>());
    const std::string layer = r["layer"];
    const EnvelopeVerdict verdict = checkEnvelope(r["text"]);
    if (layer == "envelope") {
      CHECK(verdict.code == r["code"].get<int>());
      CHECK(verdict.field == r.value("field", ""));
      continue;
    }
    // Method-level refusals pass the envelope and are always invalid params.
    REQUIRE(verdict.code == 0);
    CHECK(r["code"] == -32602);
    CHECK(r.contains("field"));
    if (layer == "op") {
      try {
        parseOp(opOf(json::parse(r["text"].get<std::string>())));
        FAIL("parseOp accepted it");
      } catch (const OpError& e) {
        CHECK(e.field() == r["field"].get<std::string>());
      }
    }
  }
}

TEST_CASE("vectors: valid ops parse to their canonical form, invalid ones name their field") {
  for (const auto& v : vectors()["ops"]["valid"]) {
    INFO(v["op"].dump());
    const Op op = parseOp(v["op"]);
    CHECK(toJson(op) == v["canonical"]);
    CHECK(parseOp(v["canonical"]) == op);
  }
  for (const auto& v : vectors()["ops"]["invalid"]) {
    INFO(v["name"].get<std::string>());
    try {
      parseOp(v["op"]);
      FAIL("parseOp accepted it");
    } catch (const OpError& e) {
      CHECK(e.field() == v["field"].get<std::string>());
    }
  }
}
