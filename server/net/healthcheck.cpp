// `marzipan healthcheck`: one HTTP/1.1 GET on a non-blocking socket, every wait a poll() bounded
// by one deadline for the whole exchange.
#include "net/healthcheck.hpp"

#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string_view>

namespace marzipan::net {

namespace {

using Clock = std::chrono::steady_clock;

constexpr int kExitHealthy = 0, kExitUnhealthy = 1, kExitUsage = 2;
// /healthz answers two bytes; anything this large is not the answer we wait for.
constexpr std::size_t kMaxResponseBytes = 64 * 1024;

struct Url {
  std::string host;  // without brackets
  std::string port;
  std::string path;
  std::string hostHeader;  // as written in the URL, brackets and port included
};

bool parsePort(std::string_view text, unsigned& port) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), port);
  return !text.empty() && ec == std::errc() && end == text.data() + text.size() && port >= 1 && port <= 65535;
}

Url parseUrl(const std::string& url) {
  constexpr std::string_view scheme = "http://";
  if (url.compare(0, scheme.size(), scheme) != 0) {
    throw std::invalid_argument("\"" + url + "\" is not an http:// URL");
  }
  const std::string rest = url.substr(scheme.size());
  const std::size_t slash = rest.find('/');
  Url u;
  u.hostHeader = rest.substr(0, slash);
  u.path = slash == std::string::npos ? "/" : rest.substr(slash);
  for (const char c : u.path) {
    if (static_cast<unsigned char>(c) <= ' ' || c == 0x7f) throw std::invalid_argument("\"" + url + "\": the path has a space or control byte");
  }
  std::string_view authority = u.hostHeader;
  std::string_view portText;
  if (authority.starts_with('[')) {
    const std::size_t close = authority.find(']');
    if (close == std::string_view::npos) throw std::invalid_argument("\"" + url + "\": '[' without ']'");
    u.host = authority.substr(1, close - 1);
    const std::string_view after = authority.substr(close + 1);
    if (!after.empty() && !after.starts_with(':')) throw std::invalid_argument("\"" + url + "\": junk after ']'");
    portText = after.empty() ? std::string_view("80") : after.substr(1);
  } else {
    const std::size_t colon = authority.find(':');
    u.host = authority.substr(0, colon);
    portText = colon == std::string_view::npos ? std::string_view("80") : authority.substr(colon + 1);
  }
  unsigned port = 0;
  if (u.host.empty()) throw std::invalid_argument("\"" + url + "\" names no host");
  if (!parsePort(portText, port)) throw std::invalid_argument("\"" + url + "\": the port is not 1…65535");
  u.port = std::to_string(port);
  return u;
}

// Milliseconds left until `deadline`, at least 0.
int msLeft(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left > 0 ? static_cast<int>(left) : 0;
}

// Waits for `events` on `fd` until the deadline; false on timeout.
bool waitFor(int fd, short events, Clock::time_point deadline) {
  for (;;) {
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, msLeft(deadline));
    if (n > 0) return true;
    if (n == 0 || errno != EINTR) return false;
  }
}

class Socket {
 public:
  explicit Socket(int fd) : fd_(fd) {}
  ~Socket() {
    if (fd_ >= 0) ::close(fd_);
  }
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;

 private:
  int fd_;
};

// Connects to the first address of `u` that takes the connection; "" on success, else the reason.
std::string connectTo(const Url& u, Clock::time_point deadline, int& fdOut) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* list = nullptr;
  if (const int rc = ::getaddrinfo(u.host.c_str(), u.port.c_str(), &hints, &list); rc != 0) {
    return std::string("cannot resolve ") + u.host + ": " + ::gai_strerror(rc);
  }
  std::string reason = "no address";
  for (const addrinfo* a = list; a; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      reason = std::string("socket: ") + std::strerror(errno);
      continue;
    }
    int error = 0;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
      error = errno;
      if (error == EINPROGRESS) {
        if (!waitFor(fd, POLLOUT, deadline)) {
          ::close(fd);
          reason = "connect timed out";
          break;
        }
        socklen_t len = sizeof error;
        ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &len);
      }
    }
    if (error == 0) {
      ::freeaddrinfo(list);
      fdOut = fd;
      return "";
    }
    ::close(fd);
    reason = std::string("connect: ") + std::strerror(error);
  }
  ::freeaddrinfo(list);
  return reason;
}

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool equalsIgnoreCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  }
  return true;
}

// A printable, short rendering of received bytes for the one-line detail.
std::string quoted(std::string_view bytes) {
  std::string q = "\"";
  for (const char c : bytes.substr(0, 40)) q += (c >= ' ' && c < 0x7f) ? c : '?';
  return q + (bytes.size() > 40 ? "...\"" : "\"");
}

// The response header, once all of it has arrived.
struct Head {
  int status = 0;                    // 0 when the status line is not HTTP/1.x
  std::optional<std::size_t> length;  // Content-Length, when given and well-formed
  std::size_t bodyStart = 0;
  std::string statusLine;
};

std::optional<Head> parseHead(const std::string& response) {
  const std::size_t end = response.find("\r\n\r\n");
  if (end == std::string::npos) return std::nullopt;
  const std::string_view head(response.data(), end);
  Head h;
  h.bodyStart = end + 4;
  std::size_t eol = head.find("\r\n");
  h.statusLine = head.substr(0, eol);
  const std::string_view line = h.statusLine;
  if (!line.starts_with("HTTP/1.") || line.size() < 12 || line[8] != ' ' ||
      std::from_chars(line.data() + 9, line.data() + 12, h.status).ec != std::errc()) {
    h.status = 0;
  }
  while (eol != std::string_view::npos) {
    const std::size_t next = head.find("\r\n", eol + 2);
    const std::string_view field = head.substr(eol + 2, next == std::string_view::npos ? std::string_view::npos : next - eol - 2);
    const std::size_t colon = field.find(':');
    if (colon != std::string_view::npos && equalsIgnoreCase(trimmed(field.substr(0, colon)), "content-length")) {
      const std::string_view value = trimmed(field.substr(colon + 1));
      std::size_t length = 0;
      const auto [ptr, ec] = std::from_chars(value.data(), value.data() + value.size(), length);
      if (ec == std::errc() && ptr == value.data() + value.size()) h.length = length;
    }
    eol = next;
  }
  return h;
}

// Healthy means 200 and the body exactly "ok"; the body is what Content-Length covers, or all
// that came before the server closed when it sent none.
HealthResult judge(const Head& h, const std::string& response) {
  if (h.status == 0) return {false, "not an HTTP/1.x answer: " + quoted(h.statusLine)};
  std::string_view body = std::string_view(response).substr(h.bodyStart);
  if (h.length) body = body.substr(0, *h.length);
  return {h.status == 200 && body == "ok", "status " + std::to_string(h.status) + ", body " + quoted(body)};
}

}  // namespace

HealthResult probeHealth(const std::string& url, std::chrono::milliseconds timeout) {
  const Url u = parseUrl(url);
  const Clock::time_point deadline = Clock::now() + timeout;
  int fd = -1;
  if (std::string reason = connectTo(u, deadline, fd); !reason.empty()) return {false, reason};
  const Socket socket(fd);

  const std::string request = "GET " + u.path + " HTTP/1.1\r\nHost: " + u.hostHeader +
                              "\r\nUser-Agent: marzipan-healthcheck\r\nConnection: close\r\n\r\n";
  for (std::size_t sent = 0; sent < request.size();) {
    if (!waitFor(fd, POLLOUT, deadline)) return {false, "sending timed out"};
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
    if (n <= 0) return {false, std::string("send: ") + std::strerror(errno)};
    sent += static_cast<std::size_t>(n);
  }

  std::string response;
  for (;;) {
    const std::optional<Head> head = parseHead(response);
    if (head && (head->status == 0 || (head->length && response.size() - head->bodyStart >= *head->length))) {
      return judge(*head, response);
    }
    if (!waitFor(fd, POLLIN, deadline)) {
      return {false, "no complete answer within " + std::to_string(timeout.count()) + " ms" +
                         (response.empty() ? std::string() : ", got " + quoted(response))};
    }
    char chunk[4096];
    const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
    if (n < 0) return {false, std::string("recv: ") + std::strerror(errno)};
    if (n == 0) {
      if (!head) return {false, "connection closed before a complete answer"};
      if (head->length) return {false, "connection closed before the whole body"};
      return judge(*head, response);
    }
    response.append(chunk, static_cast<std::size_t>(n));
    if (response.size() > kMaxResponseBytes) return {false, "answer larger than 64 KiB"};
  }
}

std::string defaultHealthUrl() {
  std::string host = "127.0.0.1";
  if (const char* bind = std::getenv("MARZIPAN_BIND"); bind && *bind) host = bind;
  if (host == "0.0.0.0") host = "127.0.0.1";
  if (host == "::" || host == "[::]") host = "::1";
  if (host.find(':') != std::string::npos && !host.starts_with('[')) host = "[" + host + "]";
  std::string port = "8080";
  if (const char* p = std::getenv("MARZIPAN_PORT"); p && *p) {
    unsigned value = 0;
    if (!parsePort(p, value)) throw std::invalid_argument(std::string("MARZIPAN_PORT \"") + p + "\" is not a port 1…65535");
    port = p;
  }
  return "http://" + host + ":" + port + "/healthz";
}

int runHealthcheck(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::string url;
  try {
    for (std::size_t i = 0; i < args.size(); ++i) {
      const std::string& arg = args[i];
      if (arg == "--help" || arg == "-h") {
        printHealthcheckUsage(out);
        return kExitHealthy;
      }
      if (arg.starts_with("--url=")) {
        url = arg.substr(6);
      } else if (arg == "--url") {
        if (i + 1 == args.size()) throw std::invalid_argument("--url needs a value");
        url = args[++i];
      } else {
        throw std::invalid_argument("unknown option \"" + arg + "\"");
      }
    }
    if (url.empty()) url = defaultHealthUrl();
    const HealthResult r = probeHealth(url);
    if (r.healthy) {
      out << url << ": healthy (" << r.detail << ")\n";
      return kExitHealthy;
    }
    err << "marzipan healthcheck: " << url << ": " << r.detail << '\n';
    return kExitUnhealthy;
  } catch (const std::invalid_argument& e) {
    err << "marzipan healthcheck: " << e.what() << "\n\n";
    printHealthcheckUsage(err);
    return kExitUsage;
  }
}

void printHealthcheckUsage(std::ostream& os) {
  os << R"(Usage: marzipan healthcheck [--url http://HOST:PORT/healthz]

Asks a running `marzipan serve` for GET /healthz and exits 0 when it answers 200 "ok" within
2 seconds, 1 otherwise (one line on stderr says why). For container health checks: no curl
needed.

Options:
  --url URL   what to ask; default /healthz at MARZIPAN_BIND (127.0.0.1 when unset, 0.0.0.0 and
              :: mean the loopback address) and MARZIPAN_PORT (8080 when unset), the variables
              `marzipan serve` reads
  --help      this text

Exit status: 0 healthy, 1 not healthy or no answer, 2 usage error (a malformed URL or
MARZIPAN_PORT). Options also take the form --name=value.
)";
}

}  // namespace marzipan::net
