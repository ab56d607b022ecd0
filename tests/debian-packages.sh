# Sourced by the install scripts: the Debian packages Marzipan builds, runs and tests with.
# What building and running `marzipan` needs (server/install-build-run.sh installs only these;
# python3 runs protocol/registry/generate.py during the build):
MARZIPAN_RUN_PACKAGES=(g++ cmake ninja-build pkg-config python3 libboost-dev nlohmann-json3-dev libstb-dev libzstd-dev libturbojpeg0-dev libmeshoptimizer-dev)
# What only the tests need (tests/install-build-test.sh installs both lists): Catch2, ccache for
# rebuilds, node for the JavaScript and browser tests, python3-websockets for the Python client
# and the process tests, python3-numpy for the load tool's picking (tests/load/web_client_model.py),
# HAProxy and openssl for the scale-out test, etcd (server and etcdctl) for the etcd-owned
# sessions' tests (serving with --etcd needs a reachable etcd, not these), Chromium for the web client, clang and its runtime for the sanitizer and fuzz builds, OpenVDB
# (and the Boost.Iostreams its CMake config asks for) for the optional .vdb build (tests/openvdb.sh),
# valgrind (callgrind and its callgrind.h) for the benchmark's instruction counts (tests/bench/instructions.py).
MARZIPAN_TEST_PACKAGES=(catch2 ccache nodejs haproxy python3-websockets python3-jsonschema python3-numpy openssl etcd-server etcd-client chromium clang libclang-rt-14-dev admesh libopenvdb-dev libboost-iostreams-dev valgrind)

# install_debian_packages PACKAGE...: installs those of the given packages that are missing.
install_debian_packages() {
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]})); then
    echo "installing: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
  fi
}
