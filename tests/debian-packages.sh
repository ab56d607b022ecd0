# Sourced by the install scripts: the Debian packages Marzipan builds and tests with.
MARZIPAN_PACKAGES=(g++ cmake ninja-build ccache pkg-config catch2 libboost-dev nlohmann-json3-dev libstb-dev libturbojpeg0-dev libmeshoptimizer-dev admesh nodejs haproxy python3-websockets openssl chromium clang libclang-rt-14-dev)

install_debian_packages() {
  local missing=()
  for p in "${MARZIPAN_PACKAGES[@]}"; do
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
