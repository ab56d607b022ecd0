// What the per-address limits (max_connections_per_address in the network layer,
// max_creates_per_address_per_minute in the hub) count as one client address.
#pragma once

#include <string>
#include <string_view>

namespace marzipan::service {

// The key of the per-address limits for a client's address, with or without its port
// ("203.0.113.7", "203.0.113.7:5000", "2001:db8::1", "[2001:db8::1]:5000"). An IPv4 address is
// itself. An IPv6 address counts by its /64 prefix ("2001:db8::/64"): one host is usually
// given a whole /64 and may take any address in it, so per address it would be 2^64 clients.
// An IPv4-mapped IPv6 address (::ffff:a.b.c.d, how a dual-stack socket sees IPv4 clients) is
// its IPv4 address, not the /64 of every IPv4 client. Text that is no address is its own key.
std::string addressLimitKey(std::string_view peer);

}  // namespace marzipan::service
