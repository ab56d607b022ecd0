// The etcd gateway client (net/etcd_client.hpp): base64, endpoints, failover, and, against
// real etcd members, the client and the etcd-owned sessions' logic (service/etcd_store.hpp).
// The [etcd-live] cases are hidden: tests/etcd/test_etcd_live.py starts three members on
// loopback and runs them with MARZIPAN_TEST_ETCD=URL,URL,URL and MARZIPAN_TEST_ETCD_PIDS
// (the members' process ids, in the same order), so that a case can kill the leader.
#include <catch2/catch.hpp>

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <thread>

#include "net/etcd_client.hpp"
#include "service/etcd_store.hpp"

using marzipan::net::base64Decode;
using marzipan::net::base64Encode;
using marzipan::net::EtcdClient;
using marzipan::service::EtcdOwner;
using marzipan::service::Fenced;
using marzipan::service::KvCompare;
using marzipan::service::KvOp;
using marzipan::service::KvRefused;
using marzipan::service::KvUnavailable;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

// A loopback port nothing listens on (bound, then closed).
std::uint16_t deadPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

std::vector<std::string> liveEndpoints() {
  const char* list = std::getenv("MARZIPAN_TEST_ETCD");
  REQUIRE(list != nullptr);
  return EtcdClient::splitEndpoints(list);
}

std::vector<pid_t> livePids() {
  const char* list = std::getenv("MARZIPAN_TEST_ETCD_PIDS");
  REQUIRE(list != nullptr);
  std::vector<pid_t> out;
  for (const std::string& p : EtcdClient::splitEndpoints(list)) out.push_back(pid_t(std::stol(p)));
  return out;
}

// A prefix of its own per test case, so that cases share the cluster without meeting.
std::string uniquePrefix(const std::string& name) {
  return "test/" + name + "/" + std::to_string(Clock::now().time_since_epoch().count()) + "/";
}

}  // namespace

TEST_CASE("etcd client: base64 as RFC 4648's vectors", "[etcd]") {
  const std::vector<std::pair<std::string, std::string>> vectors{
      {"", ""}, {"f", "Zg=="}, {"fo", "Zm8="}, {"foo", "Zm9v"}, {"foob", "Zm9vYg=="}, {"fooba", "Zm9vYmE="}, {"foobar", "Zm9vYmFy"}};
  for (const auto& [plain, coded] : vectors) {
    CHECK(base64Encode(plain) == coded);
    CHECK(base64Decode(coded) == plain);
  }
  const std::string bytes{'\0', '\xff', '\x10', '\x80'};
  CHECK(base64Decode(base64Encode(bytes)) == bytes);
  CHECK_THROWS_AS(base64Decode("Zm9v!"), std::invalid_argument);
  CHECK_THROWS_AS(base64Decode("Zg==Zg"), std::invalid_argument);
}

TEST_CASE("etcd client: endpoints are http://HOST:PORT, comma-separated", "[etcd]") {
  CHECK(EtcdClient::splitEndpoints("http://a:1,http://b:2") == std::vector<std::string>{"http://a:1", "http://b:2"});
  CHECK(EtcdClient::splitEndpoints("http://a:1,") == std::vector<std::string>{"http://a:1"});
  CHECK_THROWS_AS(EtcdClient({}), std::invalid_argument);
  CHECK_THROWS_AS(EtcdClient({"https://a:1"}), std::invalid_argument);
  CHECK_THROWS_AS(EtcdClient({"http://a"}), std::invalid_argument);
  CHECK_THROWS_AS(EtcdClient({"http://a:1/v3"}), std::invalid_argument);
  CHECK_NOTHROW(EtcdClient({"http://[::1]:2379", "http://etcd:2379/"}));
}

TEST_CASE("etcd client: no member answering is KvUnavailable, after one round of the endpoints", "[etcd]") {
  EtcdClient kv({"http://127.0.0.1:" + std::to_string(deadPort()), "http://127.0.0.1:" + std::to_string(deadPort())},
                std::chrono::milliseconds(500));
  const auto t0 = Clock::now();
  CHECK_THROWS_AS(kv.range("k"), KvUnavailable);
  CHECK_THROWS_WITH(kv.leaseGrant(5), Catch::Contains("etcd unreachable") && Catch::Contains("connect"));
  CHECK(Clock::now() - t0 < std::chrono::seconds(3));
}

// ---- against real members ---------------------------------------------------------------------

TEST_CASE("etcd live: range, txn compares, leases and failover past a dead endpoint", "[.][etcd-live]") {
  auto endpoints = liveEndpoints();
  endpoints.insert(endpoints.begin(), "http://127.0.0.1:" + std::to_string(deadPort()));
  EtcdClient kv(endpoints, std::chrono::milliseconds(1000));
  const std::string p = uniquePrefix("client");

  const std::int64_t lease = kv.leaseGrant(5);
  CHECK(lease > 0);
  CHECK(kv.leaseKeepAlive(lease) == 5);
  const KvCompare absent{p + "owner", KvCompare::Target::createRevision, KvCompare::Result::equal, 0, {}};
  const auto won = kv.txn({absent}, {KvOp{KvOp::Kind::put, p + "owner", {}, std::string("me\0\xff", 4), lease}},
                          {KvOp{KvOp::Kind::range, p + "owner", {}, {}, 0}});
  CHECK(won.succeeded);
  CHECK(won.ranges.empty());
  const auto lost = kv.txn({absent}, {KvOp{KvOp::Kind::put, p + "owner", {}, "you", 0}},
                           {KvOp{KvOp::Kind::range, p + "owner", {}, {}, 0}});
  CHECK_FALSE(lost.succeeded);
  REQUIRE(lost.ranges.size() == 1);
  REQUIRE(lost.ranges[0].size() == 1);
  CHECK(lost.ranges[0][0].value == std::string("me\0\xff", 4));
  CHECK(lost.ranges[0][0].createRevision == won.revision);  // the fencing token
  CHECK(lost.ranges[0][0].lease == lease);
  // Compare by value.
  const KvCompare isMe{p + "owner", KvCompare::Target::value, KvCompare::Result::equal, 0, std::string("me\0\xff", 4)};
  CHECK(kv.txn({isMe}, {KvOp{KvOp::Kind::put, p + "x", {}, "1", 0}}, {}).succeeded);
  // Ranges in key order with a limit; deleting a range.
  for (int k = 0; k < 5; ++k) kv.txn({}, {KvOp{KvOp::Kind::put, p + "j/" + std::to_string(k), {}, std::to_string(k), 0}}, {});
  const auto page = kv.range(p + "j/", marzipan::service::prefixEnd(p + "j/"), 3);
  REQUIRE(page.size() == 3);
  CHECK(page[2].value == "2");
  kv.txn({}, {KvOp{KvOp::Kind::deleteRange, p + "j/0", p + "j/3", {}, 0}}, {});
  CHECK(kv.range(p + "j/", marzipan::service::prefixEnd(p + "j/")).size() == 2);
  // Revoking the lease deletes the owner key; the lease is then gone.
  kv.leaseRevoke(lease);
  CHECK(kv.range(p + "owner").empty());
  CHECK(kv.leaseKeepAlive(lease) <= 0);
  CHECK_NOTHROW(kv.leaseRevoke(lease));
  // etcd's own limits refuse cleanly: a value beyond --max-request-bytes (1.5 MiB).
  CHECK_THROWS_AS(kv.txn({}, {KvOp{KvOp::Kind::put, p + "big", {}, std::string(2 << 20, 'x'), 0}}, {}), KvRefused);
  CHECK(kv.range(p + "big").empty());
}

TEST_CASE("etcd live: two servers, one owner, a paused owner past its lease is fenced by etcd", "[.][etcd-live]") {
  EtcdClient kvA(liveEndpoints()), kvB(liveEndpoints());
  marzipan::service::EtcdOptions opt;
  opt.prefix = uniquePrefix("fence");
  opt.leaseTtlSeconds = 2;
  EtcdOwner a(kvA, "a:1", opt), b(kvB, "b:1", opt);
  a.start();
  b.start();
  auto ca = a.claim("s");
  REQUIRE(ca.journal);
  ca.journal->append({json{{"r", 1}}});
  CHECK(b.claim("s").owner == "a:1");
  // A pause of a's keep-alive: etcd alone decides that the lease is over. Revoking it from
  // outside is that expiry, without waiting for it.
  const auto owner = kvB.range(a.ownerKey("s"));
  REQUIRE(owner.size() == 1);
  kvB.leaseRevoke(owner[0].lease);
  auto cb = b.claim("s");
  REQUIRE(cb.journal);
  CHECK(cb.state.journal.size() == 1);
  cb.journal->append({json{{"r", 2}}});
  CHECK_THROWS_AS(ca.journal->append({json{{"r", 99}}}), Fenced);
  const auto st = b.read("s");
  REQUIRE(st.journal.size() == 2);
  CHECK(st.journal[0].token < st.journal[1].token);
  CHECK(st.journal[1].records[0]["r"] == 2);
}

TEST_CASE("etcd live: killing the leader, appends resume after the election and none acknowledged is lost", "[.][etcd-live]") {
  const auto endpoints = liveEndpoints();
  const auto pids = livePids();
  REQUIRE(pids.size() == endpoints.size());
  EtcdClient kv(endpoints, std::chrono::milliseconds(1000));
  marzipan::service::EtcdOptions opt;
  opt.prefix = uniquePrefix("leader");
  opt.leaseTtlSeconds = 5;
  EtcdOwner owner(kv, "a:1", opt);
  owner.start();
  auto c = owner.claim("s");
  REQUIRE(c.journal);
  std::size_t leader = endpoints.size();
  for (std::size_t k = 0; k < endpoints.size(); ++k) {
    const auto st = kv.status(endpoints[k]);
    if (st.memberId == st.leader) leader = k;
  }
  REQUIRE(leader < endpoints.size());
  int acknowledged = 0;
  for (; acknowledged < 20; ++acknowledged) c.journal->append({json{{"r", acknowledged + 1}}});
  REQUIRE(::kill(pids[leader], SIGKILL) == 0);
  const auto killed = Clock::now();
  // The next append waits for the election (the client goes round the members, the store
  // retries an unknown outcome while its lease lasts).
  c.journal->append({json{{"r", ++acknowledged}}});
  const double resumed = std::chrono::duration<double>(Clock::now() - killed).count();
  WARN("first append after killing the etcd leader took " << resumed << " s");
  CHECK(resumed < 5);
  for (int k = 0; k < 20; ++k) c.journal->append({json{{"r", ++acknowledged}}});
  const auto st = owner.read("s");
  REQUIRE(st.journal.size() == std::size_t(acknowledged));
  for (int k = 0; k < acknowledged; ++k) CHECK(st.journal[k].records[0]["r"] == k + 1);
}
