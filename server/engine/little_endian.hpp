// The engine's short name for protocol/cpp/little_endian.hpp, which the protocol's codecs share.
#pragma once

#include "protocol/cpp/little_endian.hpp"
