#include "service/hub/secrets.hpp"

#include <sys/random.h>

#include <cerrno>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace marzipan::service {

std::string randomText(std::size_t chars) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
  constexpr unsigned kAlphanumerics = 62;
  std::string s;
  s.reserve(chars);
  std::vector<unsigned char> bytes(chars);
  while (s.size() < chars) {
    std::size_t got = 0;
    while (got < chars) {
      const ssize_t n = ::getrandom(bytes.data() + got, chars - got, 0);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw std::runtime_error("no random bytes from the kernel");
      got += std::size_t(n);
    }
    for (std::size_t i = 0; i < chars && s.size() < chars; ++i) {
      const unsigned v = bytes[i] & 63u;
      if (s.empty() && v >= kAlphanumerics) continue;  // rejection keeps the first character uniform
      s.push_back(kAlphabet[v]);
    }
  }
  return s;
}

bool sameSecret(const std::string& secret, const std::string& given) {
  unsigned diff = secret.size() != given.size() ? 1u : 0u;
  for (std::size_t i = 0; i < secret.size(); ++i)
    diff |= unsigned(std::uint8_t(secret[i]) ^ std::uint8_t(i < given.size() ? given[i] : 0));
  return diff == 0;
}

}  // namespace marzipan::service
