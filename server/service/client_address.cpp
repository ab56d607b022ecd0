#include "service/client_address.hpp"

#include <arpa/inet.h>

#include <array>
#include <cstring>

namespace marzipan::service {

namespace {

// The address part of a peer text: "[v6]:port" and "v6" keep their IPv6 text (without a zone
// such as "%eth0"), "v4:port" loses its port.
std::string addressPart(std::string_view peer) {
  std::string_view a = peer;
  if (!a.empty() && a.front() == '[') {
    const std::size_t close = a.find(']');
    a = a.substr(1, close == std::string_view::npos ? std::string_view::npos : close - 1);
  } else if (const std::size_t colon = a.find(':'); colon != std::string_view::npos && colon == a.rfind(':')) {
    a = a.substr(0, colon);
  }
  return std::string(a.substr(0, a.find('%')));
}

}  // namespace

std::string addressLimitKey(std::string_view peer) {
  const std::string address = addressPart(peer);
  std::array<unsigned char, 16> v6{};
  if (::inet_pton(AF_INET6, address.c_str(), v6.data()) != 1) {
    in_addr v4{};
    if (::inet_pton(AF_INET, address.c_str(), &v4) != 1) return std::string(peer);
    return address;
  }
  char text[INET6_ADDRSTRLEN] = {};
  static constexpr std::array<unsigned char, 12> kMappedPrefix = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF, 0xFF};
  if (std::memcmp(v6.data(), kMappedPrefix.data(), kMappedPrefix.size()) == 0) {
    ::inet_ntop(AF_INET, v6.data() + 12, text, sizeof text);
    return text;
  }
  std::memset(v6.data() + 8, 0, 8);
  ::inet_ntop(AF_INET6, v6.data(), text, sizeof text);
  return std::string(text) + "/64";
}

}  // namespace marzipan::service
