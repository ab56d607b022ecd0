// `marzipan serve` as a process: the built binary (test_paths::kCli) on port 0 prints where it
// listens, serves, and exits 0 on SIGTERM; bad flags exit 2. Every wait is bounded (10 s).
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "support.hpp"
#include "test_paths.hpp"

namespace fs = std::filesystem;
using marzipan::test::request;

namespace {

// A running `marzipan serve ARGS`, stdout on a pipe, stderr in a file; killed if still alive
// when destroyed.
class ServeProcess {
 public:
  ServeProcess(const std::vector<std::string>& args, const fs::path& stderrFile,
               const std::vector<std::pair<std::string, std::string>>& env = {}) {
    int fds[2];
    REQUIRE(::pipe(fds) == 0);
    pid_ = ::fork();
    REQUIRE(pid_ >= 0);
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      const int errFd = ::open(stderrFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (errFd >= 0) ::dup2(errFd, STDERR_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
      for (const auto& [name, value] : env) ::setenv(name.c_str(), value.c_str(), 1);
      std::vector<char*> argv{const_cast<char*>(marzipan::test_paths::kCli), const_cast<char*>("serve")};
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execv(marzipan::test_paths::kCli, argv.data());
      ::_exit(127);
    }
    ::close(fds[1]);
    out_ = fds[0];
  }

  ~ServeProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(out_);
  }

  // The first line of stdout, or "" if none comes within the timeout.
  std::string firstLine(std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::string line;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (line.find('\n') == std::string::npos) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      pollfd p{out_, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return "";
      char chunk[256];
      const ssize_t n = ::read(out_, chunk, sizeof chunk);
      if (n <= 0) return "";
      line.append(chunk, static_cast<std::size_t>(n));
    }
    return line.substr(0, line.find('\n'));
  }

  // Sends `signal` and waits for the exit; the exit status, or -1 (killed) after the timeout.
  int signalAndWait(int signal, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    ::kill(pid_, signal);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    int status = 0;
    while (std::chrono::steady_clock::now() < deadline) {
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  bool exited_ = false;
};

// Runs `ENV marzipan serve ARGS` through the shell, output into DIR; its exit status.
int runStatus(const std::string& args, const fs::path& dir, const std::string& env = "") {
  const std::string command = env + " '" + marzipan::test_paths::kCli + "' serve " + args + " >'" + (dir / "out.txt").string() +
                              "' 2>'" + (dir / "err.txt").string() + "'";
  const int raw = std::system(command.c_str());
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

}  // namespace

TEST_CASE("marzipan serve --port 0: prints its port, serves, exits 0 on SIGTERM and SIGINT", "[net][cli]") {
  const fs::path dir = marzipan::test::scratch("serve-cli");
  fs::create_directories(dir / "root");
  marzipan::test::writeText(dir / "root" / "index.html", "<!DOCTYPE html>");
  for (const int signal : {SIGTERM, SIGINT}) {
    INFO("signal " << signal);
    ServeProcess serve({"--port", "0", "--threads=2", "--web-root", (dir / "root").string()}, dir / "stderr.txt",
                       {{"MARZIPAN_DATA_DIR", (dir / "data").string()}, {"MARZIPAN_PORT", "not-used"}});
    const std::string line = serve.firstLine();
    std::smatch m;
    REQUIRE(std::regex_match(line, m, std::regex(R"(listening on http://127\.0\.0\.1:([0-9]+))")));
    const auto port = static_cast<std::uint16_t>(std::stoi(m[1]));
    CHECK(request(port, "GET", "/healthz").body == "ok");
    CHECK(request(port, "GET", "/").body == "<!DOCTYPE html>");
    CHECK(fs::is_directory(dir / "data"));
    CHECK(serve.signalAndWait(signal) == 0);
  }
}

TEST_CASE("marzipan serve: bad flags and values are usage errors (exit 2), a missing web root exit 1", "[net][cli]") {
  const fs::path dir = marzipan::test::scratch("serve-usage");
  CHECK(runStatus("--bogus", dir) == 2);
  CHECK(runStatus("--port", dir) == 2);
  CHECK(runStatus("--port 65536", dir) == 2);
  CHECK(runStatus("--port -1", dir) == 2);
  CHECK(runStatus("--threads many", dir) == 2);
  CHECK(runStatus("--bind localhost.invalid", dir) == 2);
  CHECK(runStatus("", dir, "MARZIPAN_PORT=http") == 2);
  CHECK(runStatus("", dir, "MARZIPAN_BIND=1.2.3") == 2);
  CHECK(runStatus("--port 0 --web-root '" + (dir / "missing").string() + "'", dir) == 1);
  CHECK(runStatus("--etcd-session-mb 8", dir) == 2);  // needs --etcd
  CHECK(runStatus("--etcd http://127.0.0.1:1 --data-dir '" + dir.string() + "' --etcd-session-keys 99", dir) == 2);
  CHECK(runStatus("--etcd http://127.0.0.1:1 --data-dir '" + dir.string() + "' --etcd-session-mb 0", dir) == 2);
  CHECK(runStatus("--help", dir) == 0);
  CHECK(runStatus("--port=0 --web-root='" + (dir / "missing").string() + "'", dir) == 1);
}
