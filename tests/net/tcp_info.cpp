// The kernel's count of data segments a socket received (TCP_INFO). In a file of its own:
// <linux/tcp.h>, which has the field, clashes with glibc's <netinet/tcp.h>, which Asio includes.
#include <linux/tcp.h>
#include <sys/socket.h>

#include <cstdint>
#include <stdexcept>

#include "support.hpp"

namespace marzipan::test {

std::uint32_t dataSegmentsIn(int fd) {
  tcp_info info{};
  socklen_t size = sizeof info;
  if (::getsockopt(fd, IPPROTO_TCP, TCP_INFO, &info, &size) != 0 || size < sizeof info)
    throw std::runtime_error("TCP_INFO without tcpi_data_segs_in");
  return info.tcpi_data_segs_in;
}

}  // namespace marzipan::test
