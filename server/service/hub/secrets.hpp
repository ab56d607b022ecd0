// Session ids and secrets (edit and view tokens), and their comparison with what a client sends.
//
// Conventions: text over the URL-safe base64 alphabet [A-Za-z0-9-_], 6 bits a character, from
// the kernel's getrandom(). Ids and secrets begin with a letter or digit so that no command line
// takes one for an option (`--join -x...`): the first character carries log2(62) bits, not 6.
#pragma once

#include <cstddef>
#include <string>

namespace marzipan::service {

inline constexpr std::size_t kSessionIdChars = 22;  // 132 bits
inline constexpr std::size_t kTokenChars = 43;      // 258 bits

// `chars` random characters as above. Throws std::runtime_error when the kernel has no entropy.
std::string randomText(std::size_t chars);

// Whether `given` equals `secret`, in time that depends only on the secret's length.
bool sameSecret(const std::string& secret, const std::string& given);

}  // namespace marzipan::service
