#include "net/etcd_client.hpp"

#include <array>
#include <optional>
#include <stdexcept>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace marzipan::net {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using json = nlohmann::json;
using service::KvCompare;
using service::KvEntry;
using service::KvOp;

namespace {

// An answer larger than this is not one the store asked for (ranges are paged by 512 keys).
constexpr std::size_t kMaxAnswerBytes = 64 * 1024 * 1024;

// gRPC status codes etcd puts in a gateway error's "code".
constexpr int kGrpcNotFound = 5, kGrpcUnavailable = 14;

constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

// The gateway writes 64-bit numbers as strings and leaves out fields at their default.
std::int64_t number(const json& j, const char* field) {
  const auto it = j.find(field);
  if (it == j.end() || it->is_null()) return 0;
  if (it->is_string()) return std::stoll(it->get<std::string>());
  return it->get<std::int64_t>();
}

KvEntry entryOf(const json& kv) {
  KvEntry e;
  e.key = base64Decode(kv.value("key", ""));
  e.value = base64Decode(kv.value("value", ""));
  e.createRevision = number(kv, "create_revision");
  e.modRevision = number(kv, "mod_revision");
  e.lease = number(kv, "lease");
  return e;
}

std::vector<KvEntry> entriesOf(const json& rangeResponse) {
  std::vector<KvEntry> out;
  if (const auto it = rangeResponse.find("kvs"); it != rangeResponse.end())
    for (const json& kv : *it) out.push_back(entryOf(kv));
  return out;
}

json opJson(const KvOp& op) {
  json body{{"key", base64Encode(op.key)}};
  if (!op.rangeEnd.empty()) body["range_end"] = base64Encode(op.rangeEnd);
  switch (op.kind) {
    case KvOp::Kind::put:
      body["value"] = base64Encode(op.value);
      if (op.lease != 0) body["lease"] = std::to_string(op.lease);
      return {{"request_put", body}};
    case KvOp::Kind::deleteRange:
      return {{"request_delete_range", body}};
    case KvOp::Kind::range:
      return {{"request_range", body}};
  }
  throw std::logic_error("unknown KvOp kind");
}

json compareJson(const KvCompare& c) {
  json body{{"key", base64Encode(c.key)},
            {"result", c.result == KvCompare::Result::equal ? "EQUAL" : "NOT_EQUAL"}};
  if (c.target == KvCompare::Target::createRevision) {
    body["target"] = "CREATE";
    body["create_revision"] = std::to_string(c.revision);
  } else {
    body["target"] = "VALUE";
    body["value"] = base64Encode(c.value);
  }
  return body;
}

// One POST on a connection of its own, every step bounded by one deadline. Returns nullopt on a
// connection error or timeout; otherwise the status and body.
struct Answer {
  unsigned status;
  std::string body;
};
std::optional<Answer> exchange(const std::string& host, const std::string& port, const std::string& path,
                               const std::string& body, std::chrono::milliseconds timeout, std::string& error) {
  asio::io_context ioc;
  asio::ip::tcp::resolver resolver(ioc);
  beast::tcp_stream stream(ioc);
  http::request<http::string_body> req{http::verb::post, path, 11};
  req.set(http::field::host, host + ":" + port);
  req.set(http::field::content_type, "application/json");
  req.body() = body;
  req.prepare_payload();
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.body_limit(kMaxAnswerBytes);
  beast::error_code failed;
  bool done = false;
  const auto fail = [&](beast::error_code ec, const char* what) {
    failed = ec;
    error = std::string(what) + ": " + ec.message();
  };
  stream.expires_after(timeout);
  resolver.async_resolve(host, port, [&](beast::error_code ec, asio::ip::tcp::resolver::results_type results) {
    if (ec) return fail(ec, "resolve");
    stream.async_connect(results, [&](beast::error_code ec2, const asio::ip::tcp::endpoint&) {
      if (ec2) return fail(ec2, "connect");
      http::async_write(stream, req, [&](beast::error_code ec3, std::size_t) {
        if (ec3) return fail(ec3, "write");
        http::async_read(stream, buffer, parser, [&](beast::error_code ec4, std::size_t) {
          if (ec4) return fail(ec4, "read");
          done = true;
        });
      });
    });
  });
  // The resolver has no deadline of its own: the whole exchange is bounded here.
  ioc.run_for(timeout + std::chrono::milliseconds(100));
  if (!done) {
    if (!failed) error = "no answer within " + std::to_string(timeout.count()) + " ms";
    return std::nullopt;
  }
  beast::error_code ignored;
  stream.socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  return Answer{parser.get().result_int(), parser.get().body()};
}

}  // namespace

std::string base64Encode(const std::string& bytes) {
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16 | std::uint32_t(std::uint8_t(bytes[i + 1])) << 8 |
                            std::uint8_t(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += kAlphabet[(v >> s) & 63];
  }
  const std::size_t rest = bytes.size() - i;
  if (rest > 0) {
    std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16;
    if (rest == 2) v |= std::uint32_t(std::uint8_t(bytes[i + 1])) << 8;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += rest == 2 ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string base64Decode(const std::string& text) {
  std::array<int, 256> value;
  value.fill(-1);
  for (int k = 0; k < 64; ++k) value[std::uint8_t(kAlphabet[k])] = k;
  std::string out;
  std::uint32_t acc = 0;
  int bits = 0;
  std::size_t padding = 0;
  for (const char c : text) {
    if (c == '=') {
      ++padding;
      continue;
    }
    const int v = value[std::uint8_t(c)];
    if (v < 0 || padding > 0) throw std::invalid_argument("not base64");
    acc = acc << 6 | std::uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += char((acc >> bits) & 0xff);
    }
  }
  if (padding > 2) throw std::invalid_argument("not base64");
  return out;
}

EtcdClient::EtcdClient(std::vector<std::string> endpoints, std::chrono::milliseconds timeout)
    : endpoints_(std::move(endpoints)), timeout_(timeout) {
  if (endpoints_.empty()) throw std::invalid_argument("no etcd endpoint");
  for (const std::string& e : endpoints_) {
    constexpr std::string_view scheme = "http://";
    std::string rest = e.starts_with(scheme) ? e.substr(scheme.size()) : std::string();
    if (!rest.empty() && rest.back() == '/') rest.pop_back();
    const std::size_t colon = rest.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == rest.size() || rest.find('/') != std::string::npos ||
        rest.substr(colon + 1).find_first_not_of("0123456789") != std::string::npos)
      throw std::invalid_argument("etcd endpoint \"" + e + "\" is not http://HOST:PORT");
    std::string host = rest.substr(0, colon);
    if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
    parsed_.push_back(Endpoint{host, rest.substr(colon + 1), e});
  }
}

std::vector<std::string> EtcdClient::splitEndpoints(const std::string& list) {
  std::vector<std::string> out;
  std::size_t from = 0;
  while (from <= list.size()) {
    const std::size_t comma = list.find(',', from);
    const std::string one = list.substr(from, comma == std::string::npos ? std::string::npos : comma - from);
    if (!one.empty()) out.push_back(one);
    if (comma == std::string::npos) break;
    from = comma + 1;
  }
  return out;
}

json EtcdClient::post(const std::string& path, const json& body) {
  const std::string text = body.dump();
  std::string errors;
  const std::size_t first = preferred_.load();
  for (std::size_t k = 0; k < parsed_.size(); ++k) {
    const std::size_t at = (first + k) % parsed_.size();
    const Endpoint& ep = parsed_[at];
    std::string error;
    const auto answer = exchange(ep.host, ep.port, path, text, timeout_, error);
    if (!answer) {
      errors += (errors.empty() ? "" : "; ") + ep.text + ": " + error;
      continue;
    }
    const json reply = json::parse(answer->body, nullptr, false);
    if (answer->status == 200 && reply.is_object()) {
      preferred_ = at;
      return reply;
    }
    const std::string message = reply.is_object() ? reply.value("error", reply.value("message", answer->body)) : answer->body;
    const int code = reply.is_object() ? int(number(reply, "code")) : 0;
    if (code == kGrpcUnavailable || answer->status >= 502) {
      // This member cannot serve (no leader, being stopped): another one may.
      errors += (errors.empty() ? "" : "; ") + ep.text + ": " + message;
      continue;
    }
    if (code == kGrpcNotFound && path == "/v3/lease/revoke") return json::object();  // already gone
    throw service::KvRefused("etcd refused " + path + ": " + message);
  }
  throw service::KvUnavailable("etcd unreachable (" + errors + ")");
}

std::int64_t EtcdClient::leaseGrant(std::int64_t ttlSeconds) {
  const json r = post("/v3/lease/grant", {{"TTL", std::to_string(ttlSeconds)}});
  const std::int64_t id = number(r, "ID");
  if (id == 0) throw service::KvRefused("etcd granted no lease: " + r.dump());
  return id;
}

std::int64_t EtcdClient::leaseKeepAlive(std::int64_t lease) {
  // A stream on the gateway: one request in the body, one {"result":...} line back.
  // An expired lease answers TTL 0, or (as a stream's error, still HTTP 200) "not found".
  json r;
  try {
    r = post("/v3/lease/keepalive", {{"ID", std::to_string(lease)}});
  } catch (const service::KvRefused&) {
    return 0;
  }
  if (const auto e = r.find("error"); e != r.end()) {
    if (number(*e, "code") == kGrpcNotFound) return 0;
    throw service::KvUnavailable("etcd keep-alive: " + e->dump());
  }
  return number(r.value("result", json::object()), "TTL");
}

void EtcdClient::leaseRevoke(std::int64_t lease) { post("/v3/lease/revoke", {{"ID", std::to_string(lease)}}); }

std::vector<KvEntry> EtcdClient::range(const std::string& key, const std::string& rangeEnd, std::int64_t limit) {
  json body{{"key", base64Encode(key)}};
  if (!rangeEnd.empty()) body["range_end"] = base64Encode(rangeEnd);
  if (limit > 0) body["limit"] = std::to_string(limit);
  return entriesOf(post("/v3/kv/range", body));
}

service::KvTxnResult EtcdClient::txn(const std::vector<KvCompare>& compares, const std::vector<KvOp>& success,
                                     const std::vector<KvOp>& failure) {
  json body{{"compare", json::array()}, {"success", json::array()}, {"failure", json::array()}};
  for (const KvCompare& c : compares) body["compare"].push_back(compareJson(c));
  for (const KvOp& op : success) body["success"].push_back(opJson(op));
  for (const KvOp& op : failure) body["failure"].push_back(opJson(op));
  const json r = post("/v3/kv/txn", body);
  service::KvTxnResult out;
  out.succeeded = r.value("succeeded", false);
  out.revision = number(r.value("header", json::object()), "revision");
  if (const auto it = r.find("responses"); it != r.end())
    for (const json& resp : *it)
      if (const auto rr = resp.find("response_range"); rr != resp.end()) out.ranges.push_back(entriesOf(*rr));
  return out;
}

EtcdClient::MemberStatus EtcdClient::status(const std::string& endpoint) {
  for (const Endpoint& ep : parsed_) {
    if (ep.text != endpoint) continue;
    std::string error;
    const auto answer = exchange(ep.host, ep.port, "/v3/maintenance/status", "{}", timeout_, error);
    if (!answer || answer->status != 200) throw service::KvUnavailable("etcd " + endpoint + ": no status (" + error + ")");
    const json r = json::parse(answer->body);
    return MemberStatus{std::uint64_t(std::stoull(r.value("header", json::object()).value("member_id", "0"))),
                        std::uint64_t(std::stoull(r.value("leader", "0")))};
  }
  throw std::invalid_argument("not an endpoint of this client: " + endpoint);
}

}  // namespace marzipan::net
