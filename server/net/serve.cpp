// `marzipan serve`: parses flags and MARZIPAN_* variables, creates the data directory, runs
// HttpServer until a signal. The default web root is the source tree's web-client/
// (net/default_paths.hpp).
#include "net/serve.hpp"

#include <arpa/inet.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string_view>
#include <thread>
#include <type_traits>

#include "engine/thread_pool.hpp"
#include "net/default_paths.hpp"
#include "net/etcd_client.hpp"
#include "net/http_server.hpp"
#include "service/etcd_storage.hpp"
#include "service/hub.hpp"


namespace fs = std::filesystem;

namespace marzipan::net {

namespace {

constexpr int kExitOk = 0, kExitUsage = 2;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Setting {
  std::string_view flag, env;
  std::optional<std::string> value;
};

unsigned parseUnsigned(const Setting& s, unsigned max) {
  const std::string& text = *s.value;
  unsigned v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || v > max) {
    throw UsageError(std::string(s.flag) + " (or " + std::string(s.env) + "): \"" + text + "\" is not an integer 0…" +
                     std::to_string(max));
  }
  return v;
}

bool isIpAddress(const std::string& text) {
  unsigned char buffer[16];
  return inet_pton(AF_INET, text.c_str(), buffer) == 1 || inet_pton(AF_INET6, text.c_str(), buffer) == 1;
}

int serve(const std::vector<std::string>& args, std::ostream& out) {
  Setting bind{"--bind", "MARZIPAN_BIND", {}}, port{"--port", "MARZIPAN_PORT", {}},
      threads{"--threads", "MARZIPAN_THREADS", {}}, webRoot{"--web-root", "MARZIPAN_WEB_ROOT", {}},
      protocolJs{"--protocol-js", "MARZIPAN_PROTOCOL_JS", {}}, dataDir{"--data-dir", "MARZIPAN_DATA_DIR", {}},
      origins{"--allowed-origins", "MARZIPAN_ALLOWED_ORIGINS", {}},
      maxText{"--max-text-bytes", "MARZIPAN_MAX_TEXT_BYTES", {}},
      maxBinary{"--max-binary-bytes", "MARZIPAN_MAX_BINARY_BYTES", {}},
      maxGrid{"--max-grid-side", "MARZIPAN_MAX_GRID_SIDE", {}},
      maxSessions{"--max-sessions", "MARZIPAN_MAX_SESSIONS", {}},
      maxClients{"--max-clients-per-session", "MARZIPAN_MAX_CLIENTS_PER_SESSION", {}},
      maxDabs{"--max-dabs", "MARZIPAN_MAX_DABS", {}}, maxFrame{"--max-frame-side", "MARZIPAN_MAX_FRAME_SIDE", {}},
      historyMb{"--history-mb", "MARZIPAN_HISTORY_MB", {}},
      idleSeconds{"--idle-session-seconds", "MARZIPAN_IDLE_SESSION_SECONDS", {}},
      pingSeconds{"--ping-seconds", "MARZIPAN_PING_SECONDS", {}},
      queueMb{"--max-queue-mb", "MARZIPAN_MAX_QUEUE_MB", {}}, fsyncMs{"--fsync-ms", "MARZIPAN_FSYNC_MS", {}},
      serverId{"--server-id", "MARZIPAN_SERVER_ID", {}},
      maxRate{"--max-requests-per-second", "MARZIPAN_MAX_REQUESTS_PER_SECOND", {}},
      publicHosts{"--public-host", "MARZIPAN_PUBLIC_HOST", {}},
      maxConnections{"--max-connections", "MARZIPAN_MAX_CONNECTIONS", {}},
      maxPerAddress{"--max-connections-per-address", "MARZIPAN_MAX_CONNECTIONS_PER_ADDRESS", {}},
      lobbySeconds{"--lobby-seconds", "MARZIPAN_LOBBY_SECONDS", {}},
      volumeMb{"--max-volume-mb", "MARZIPAN_MAX_VOLUME_MB", {}}, outputMb{"--max-output-mb", "MARZIPAN_MAX_OUTPUT_MB", {}},
      vdbMb{"--max-vdb-mb", "MARZIPAN_MAX_VDB_MB", {}},
      createRate{"--max-creates-per-minute", "MARZIPAN_MAX_CREATES_PER_MINUTE", {}},
      createRateAddress{"--max-creates-per-address-per-minute", "MARZIPAN_MAX_CREATES_PER_ADDRESS_PER_MINUTE", {}},
      maxAgeDays{"--max-session-age-days", "MARZIPAN_MAX_SESSION_AGE_DAYS", {}},
      maxOpMvoxels{"--max-op-mvoxels", "MARZIPAN_MAX_OP_MVOXELS", {}}, etcd{"--etcd", "MARZIPAN_ETCD", {}},
      etcdLease{"--etcd-lease-seconds", "MARZIPAN_ETCD_LEASE_SECONDS", {}},
      etcdSessionMb{"--etcd-session-mb", "MARZIPAN_ETCD_SESSION_MB", {}},
      etcdSessionKeys{"--etcd-session-keys", "MARZIPAN_ETCD_SESSION_KEYS", {}};
  Setting* const settings[] = {&bind,        &port,        &threads,    &webRoot,  &protocolJs, &dataDir,
                               &origins,     &maxText,     &maxBinary,  &maxGrid,  &maxSessions, &maxClients,
                               &maxDabs,     &maxFrame,    &historyMb,  &idleSeconds, &pingSeconds, &queueMb, &fsyncMs, &serverId, &maxRate,
                               &publicHosts, &maxConnections, &maxPerAddress, &lobbySeconds,
                               &volumeMb, &outputMb, &vdbMb, &createRate, &createRateAddress, &maxAgeDays, &maxOpMvoxels,
                               &etcd,      &etcdLease, &etcdSessionMb, &etcdSessionKeys};

  for (Setting* s : settings) {
    const char* v = std::getenv(std::string(s->env).c_str());
    if (v && *v) s->value = v;  // set but empty = unset
  }
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      printServeUsage(out);
      return kExitOk;
    }
    const std::size_t eq = arg.find('=');
    const std::string_view name = std::string_view(arg).substr(0, eq);
    Setting* match = nullptr;
    for (Setting* s : settings) {
      if (s->flag == name) match = s;
    }
    if (!match) throw UsageError("unknown option \"" + arg + "\"");
    if (eq != std::string::npos) {
      match->value = arg.substr(eq + 1);
    } else {
      if (i + 1 == args.size()) throw UsageError(arg + " needs a value");
      match->value = args[++i];
    }
  }

  HttpServerOptions options;
  if (bind.value) {
    if (!isIpAddress(*bind.value)) throw UsageError("--bind (or MARZIPAN_BIND): \"" + *bind.value + "\" is not an IPv4 or IPv6 address");
    options.bind = *bind.value;
  }
  if (port.value) options.port = static_cast<std::uint16_t>(parseUnsigned(port, 65535));
  const unsigned threadCount = threads.value ? parseUnsigned(threads, 1024) : 0;
  const unsigned cores = usableCores();
  // Sockets need little CPU; geometry runs on the hub's workers.
  options.threads = std::min(2u, cores);

  // Declared before the hub's options, which share the storage that uses it: destroyed last.
  std::unique_ptr<EtcdClient> etcdClient;
  service::HubOptions hubOptions;
  hubOptions.workers = threadCount ? threadCount : cores;
  service::HubLimits& limits = hubOptions.limits;
  const auto setLimit = [](const Setting& st, auto& field, unsigned lo, unsigned hi, std::uint64_t scale = 1) {
    if (!st.value) return;
    const unsigned v = parseUnsigned(st, hi);
    if (v < lo) throw UsageError(std::string(st.flag) + " (or " + std::string(st.env) + ") must be at least " + std::to_string(lo));
    field = static_cast<std::remove_reference_t<decltype(field)>>(v * scale);
  };
  setLimit(maxText, limits.maxTextBytes, 1024, 1u << 30);
  setLimit(maxBinary, limits.maxBinaryBytes, 1024, 4000000000u);
  setLimit(maxGrid, limits.maxGridSide, 8, 1024);
  setLimit(maxSessions, limits.maxSessions, 1, 100000);
  setLimit(maxClients, limits.maxClientsPerSession, 1, 10000);
  setLimit(maxDabs, limits.maxDabs, 1, 100000);
  setLimit(maxFrame, limits.maxFrameSide, 16, 4096);
  setLimit(historyMb, limits.historyBytes, 0, 1u << 20, std::uint64_t(1) << 20);
  setLimit(maxRate, limits.maxRequestsPerSecond, 1, 1000000);
  setLimit(queueMb, limits.maxQueuedBytes, 1, 1u << 16, std::uint64_t(1) << 20);
  setLimit(maxOpMvoxels, limits.maxOpVoxels, 1, 1u << 30, 1'000'000);
  if (serverId.value) {
    const bool ok = std::all_of(serverId.value->begin(), serverId.value->end(), [](char ch) {
      return std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_' || ch == ':' || ch == '-';
    });
    if (!ok) throw UsageError("--server-id (or MARZIPAN_SERVER_ID): only letters, digits and . _ : - are allowed");
    hubOptions.serverId = *serverId.value;
  } else if (options.port != 0) {
    // Stable across restarts of this server, distinct between servers of one host.
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) == 0) hubOptions.serverId = std::string(host) + ":" + std::to_string(options.port);
  }
  if (fsyncMs.value) hubOptions.fsyncInterval = std::chrono::milliseconds(parseUnsigned(fsyncMs, 60'000));
  if (idleSeconds.value) limits.idleSession = std::chrono::seconds(parseUnsigned(idleSeconds, 1u << 30));
  if (pingSeconds.value) {
    limits.ping = std::chrono::seconds(parseUnsigned(pingSeconds, 3600));
    if (limits.ping.count() < 1) throw UsageError("--ping-seconds (or MARZIPAN_PING_SECONDS) must be at least 1");
  }
  setLimit(volumeMb, limits.maxVolumeBytes, 1, 1u << 20, std::uint64_t(1) << 20);
  setLimit(outputMb, limits.maxOutputBytes, 1, 4095, std::uint64_t(1) << 20);
  setLimit(vdbMb, limits.maxVdbBytes, 1, 4095, std::uint64_t(1) << 20);
  setLimit(createRate, limits.maxCreatesPerMinute, 1, 1000000);
  setLimit(createRateAddress, limits.maxCreatesPerAddressPerMinute, 1, 1000000);
  if (maxAgeDays.value) {
    limits.maxSessionAge = std::chrono::hours(24 * std::int64_t(parseUnsigned(maxAgeDays, 100000)));
    if (limits.maxSessionAge.count() < 24) throw UsageError("--max-session-age-days (or MARZIPAN_MAX_SESSION_AGE_DAYS) must be at least 1");
  }
  setLimit(maxConnections, limits.maxConnections, 1, 1000000);
  setLimit(maxPerAddress, limits.maxConnectionsPerAddress, 1, 1000000);
  if (lobbySeconds.value) {
    limits.lobby = std::chrono::seconds(parseUnsigned(lobbySeconds, 1u << 30));
    if (limits.lobby.count() < 1) throw UsageError("--lobby-seconds (or MARZIPAN_LOBBY_SECONDS) must be at least 1");
  }
  const auto splitList = [](const std::optional<std::string>& value, std::vector<std::string>& into) {
    if (!value) return;
    std::string_view list = *value;
    while (!list.empty()) {
      const std::size_t comma = list.find(',');
      const std::string_view item = list.substr(0, comma);
      if (!item.empty()) into.emplace_back(item);
      list = comma == std::string_view::npos ? std::string_view() : list.substr(comma + 1);
    }
  };
  splitList(origins.value, options.allowedOrigins);
  splitList(publicHosts.value, options.publicHosts);
  options.webRoot = webRoot.value ? fs::path(*webRoot.value) : fs::path(kDefaultWebRoot);
  if (webRoot.value && webRoot.value->empty()) throw UsageError("--web-root (or MARZIPAN_WEB_ROOT) is empty");
  std::error_code ec;
  if (!fs::is_directory(options.webRoot, ec)) {
    throw std::runtime_error("web root " + options.webRoot.string() + " is not a directory; pass --web-root DIR");
  }
  const fs::path jsDir = protocolJs.value ? fs::path(*protocolJs.value) : fs::path(kDefaultProtocolJs);
  if (fs::is_directory(jsDir, ec)) options.mounts.emplace_back("/protocol/js/", jsDir);
  else if (protocolJs.value) throw std::runtime_error("protocol js directory " + jsDir.string() + " is not a directory");
  if (dataDir.value) {
    if (dataDir.value->empty()) throw UsageError("--data-dir (or MARZIPAN_DATA_DIR) is empty");
    fs::create_directories(*dataDir.value, ec);
    if (ec) throw std::runtime_error("cannot create data directory " + *dataDir.value + ": " + ec.message());
    hubOptions.dataDir = *dataDir.value;
  }
  for (const Setting* s : {&etcdLease, &etcdSessionMb, &etcdSessionKeys})
    if (s->value && !etcd.value) throw UsageError(std::string(s->flag) + " needs --etcd");
  service::EtcdOptions etcdOptions;
  if (etcdLease.value) {
    etcdOptions.leaseTtlSeconds = parseUnsigned(etcdLease, 3600);
    if (etcdOptions.leaseTtlSeconds < 2) throw UsageError("--etcd-lease-seconds (or MARZIPAN_ETCD_LEASE_SECONDS) must be at least 2");
  }
  if (etcdSessionMb.value) {
    etcdOptions.maxSessionBytes = std::size_t(parseUnsigned(etcdSessionMb, 8192)) << 20;
    if (etcdOptions.maxSessionBytes == 0) throw UsageError("--etcd-session-mb (or MARZIPAN_ETCD_SESSION_MB) must be at least 1");
  }
  if (etcdSessionKeys.value) {
    etcdOptions.maxSessionKeys = parseUnsigned(etcdSessionKeys, 10'000'000);
    if (etcdOptions.maxSessionKeys < 100)
      throw UsageError("--etcd-session-keys (or MARZIPAN_ETCD_SESSION_KEYS) must be at least 100");
  }
  if (etcd.value && !dataDir.value)
    throw UsageError("--etcd (or MARZIPAN_ETCD) needs --data-dir: the snapshots are files on a volume the servers share");
  options.handleSignals = true;
  // A write past a file size limit (ulimit -f) must fail with EFBIG and be refused like a full
  // disk, not kill the server.
  std::signal(SIGXFSZ, SIG_IGN);

  HttpServer server(options);
  hubOptions.events = hubEventsFor(server.metrics());
  hubOptions.events.log = logToStderr;
  if (etcd.value) {
    try {
      etcdClient = std::make_unique<EtcdClient>(EtcdClient::splitEndpoints(*etcd.value));
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--etcd (or MARZIPAN_ETCD): ") + e.what());
    }
    // The owner keys name this server: its id, which clients are told with -32015.
    if (hubOptions.serverId.empty()) {
      char host[256] = {};
      ::gethostname(host, sizeof host - 1);
      hubOptions.serverId = std::string(host) + "-" + std::to_string(::getpid());
    }
    service::EtcdEvents events = etcdEventsFor(server.metrics());
    events.log = logToStderr;
    hubOptions.storage = std::make_shared<service::EtcdStorage>(*etcdClient, *dataDir.value, hubOptions.serverId,
                                                                etcdOptions, std::move(events));
  }
  service::Hub hub(hubOptions);
  server.setHub(&hub);
  server.start();
  const std::string host = options.bind.find(':') != std::string::npos ? "[" + options.bind + "]" : options.bind;
  out << "listening on http://" << host << ':' << server.port() << std::endl;
  server.waitForStopRequest();
  server.stop();
  return kExitOk;
}

}  // namespace

int runServe(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  try {
    return serve(args, out);
  } catch (const UsageError& e) {
    err << "marzipan serve: " << e.what() << "\n\n";
    printServeUsage(err);
    return kExitUsage;
  }
}

void printServeUsage(std::ostream& os) {
  os << R"(Usage: marzipan serve [options]

Serves the browser client (the files of the web root) at /, the JavaScript protocol modules at
/protocol/js/, /healthz (200 "ok"), /metrics (Prometheus text), and the sculpting API as
JSON-RPC over a WebSocket at /ws (protocol/PROTOCOL.md).

Options (each also read from the environment variable in brackets; a flag wins):
  --bind ADDR       IPv4 or IPv6 address to listen on [MARZIPAN_BIND]; default 127.0.0.1,
                    0.0.0.0 for every interface
  --port N          TCP port, 0 = pick a free one [MARZIPAN_PORT]; default 8080
  --threads N       worker threads for sculpting and rendering, 0 = one per core
                    [MARZIPAN_THREADS]; default one per core
  --web-root DIR    directory served at / [MARZIPAN_WEB_ROOT]; default the source tree's
                    web-client/
  --protocol-js DIR directory served at /protocol/js/ [MARZIPAN_PROTOCOL_JS]; default the
                    source tree's protocol/js/
  --data-dir DIR    where sessions are journaled, snapshotted and loaded again, created if
                    missing [MARZIPAN_DATA_DIR]; without it sessions live in memory only and an
                    idle one is discarded
  --server-id NAME  this server's name in session leases [MARZIPAN_SERVER_ID]; default
                    HOSTNAME:PORT (random with --port 0). Restarted under the same name it
                    takes its sessions back at once; other servers wait for the lease (30 s;
                    with --etcd the etcd lease, see below: not even the same name skips it)
  --etcd URL[,URL...]  own sessions through etcd (3.4+, its v3 JSON gateway: http://HOST:PORT of
                    each member) [MARZIPAN_ETCD]; needs --data-dir on a volume every server
                    mounts (snapshots stay files there). Owner, journal and snapshot pointer
                    live in etcd, fenced: a server that lost its lease can write nothing.
                    Without it the data directory's lease files decide (one host's clock)
  --etcd-lease-seconds N  with --etcd: this server's lease TTL; its sessions move to another
                    server that long after it dies (at once after a clean stop)
                    [MARZIPAN_ETCD_LEASE_SECONDS]; 5
  --etcd-session-mb N, --etcd-session-keys N  with --etcd: what one session may hold in etcd
                    (its journal, snapshot pointer and owner key); an edit past it gets
                    -32004 [MARZIPAN_ETCD_SESSION_MB, MARZIPAN_ETCD_SESSION_KEYS]; 16, 10000
  --fsync-ms N      0: every change is fsynced before its response (default); N: at most
                    every N ms, a crash may lose that much [MARZIPAN_FSYNC_MS]
  --allowed-origins LIST  comma-separated origins (http://host:port) that browsers may open
                    /ws from, * for any [MARZIPAN_ALLOWED_ORIGINS]; default the page's own
                    when it was served under an address literal, localhost or a --public-host
  --public-host LIST  comma-separated host names browsers reach this server by (behind a
                    proxy: its public name) [MARZIPAN_PUBLIC_HOST]; other names are refused
                    for the page's-own origin check (DNS rebinding)
Limits (PROTOCOL.md, "Versions and limits"):
  --max-text-bytes N         largest text message [MARZIPAN_MAX_TEXT_BYTES]; 1048576
  --max-binary-bytes N       largest binary message [MARZIPAN_MAX_BINARY_BYTES]; 268435456
  --max-grid-side N          largest grid side of a session [MARZIPAN_MAX_GRID_SIDE]; 512
  --max-sessions N           sessions loaded at once [MARZIPAN_MAX_SESSIONS]; 64
  --max-clients-per-session N  [MARZIPAN_MAX_CLIENTS_PER_SESSION]; 16
  --max-dabs N               dabs in one stroke.dabs [MARZIPAN_MAX_DABS]; 256
  --max-frame-side N         largest frame width/height [MARZIPAN_MAX_FRAME_SIDE]; 4096
  --history-mb N             undo memory per session [MARZIPAN_HISTORY_MB]; 64
  --idle-session-seconds N   a session without clients this long is saved and unloaded
                             [MARZIPAN_IDLE_SESSION_SECONDS]; 600
  --ping-seconds N           WebSocket ping period; two without answer close
                             [MARZIPAN_PING_SECONDS]; 30
  --max-requests-per-second N  per connection, bursts of twice that; beyond: busy (-32005)
                             [MARZIPAN_MAX_REQUESTS_PER_SECOND]; 400
  --max-queue-mb N           undelivered responses and splat buffers per connection before it
                             is closed as too far behind; one answer counts at most half
                             [MARZIPAN_MAX_QUEUE_MB]; 64
  --max-connections N        TCP connections at once; more are closed at once
                             [MARZIPAN_MAX_CONNECTIONS]; 1024
  --max-connections-per-address N  the same per client address
                             [MARZIPAN_MAX_CONNECTIONS_PER_ADDRESS]; 32
  --lobby-seconds N          a WebSocket in no session this long is closed (1008)
                             [MARZIPAN_LOBBY_SECONDS]; 60
  --max-volume-mb N          memory of one session's volume; a larger volume.load is
                             refused [MARZIPAN_MAX_VOLUME_MB]; 256
  --max-output-mb N          largest mesh file or splat buffer one request may build,
                             estimated before any work [MARZIPAN_MAX_OUTPUT_MB]; 256
  --max-vdb-mb N             largest .vdb file a volume.load may send (reading one takes
                             up to ~33 times its size) [MARZIPAN_MAX_VDB_MB]; 16
  --max-creates-per-minute N   session.create per connection in 60 s
                             [MARZIPAN_MAX_CREATES_PER_MINUTE]; 10
  --max-creates-per-address-per-minute N  the same per client address
                             [MARZIPAN_MAX_CREATES_PER_ADDRESS_PER_MINUTE]; 30
  --max-session-age-days N   with --data-dir: a session at rest nobody changed for N days is
                             deleted [MARZIPAN_MAX_SESSION_AGE_DAYS]; 90
  --max-op-mvoxels N         work one request may cost, in millions of voxels processed
                             (estimated before it runs); beyond: -32004 [MARZIPAN_MAX_OP_MVOXELS]; 4000
  --help            this text

Prints "listening on http://HOST:PORT" once it accepts connections and logs connection and
session events to stderr. SIGINT or SIGTERM: stops accepting, cancels long operations (they
change nothing), finishes other running edits, saves sessions (with --data-dir), closes
WebSockets with 1001 and exits 0, within 10 s.
Exit status: 0 after a signal, 1 when it cannot start (web root missing, port in use),
2 usage error. Options also take the form --name=value.
)";
}

}  // namespace marzipan::net
