// The engine's short name for common/little_endian.hpp, which the protocol's codecs share.
#pragma once

#include "common/little_endian.hpp"
