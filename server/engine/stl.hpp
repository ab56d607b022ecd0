// STL files (conventions in mesh_format.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "mesh_format.hpp"

namespace marzipan {

// Binary STL: 80-byte header, uint32 count, per triangle the unit face normal (zero when
// degenerate), three vertices and a zero uint16.
std::vector<std::uint8_t> exportStl(const Mesh& m);

// STL, binary (when the size is exactly 84 + 50 * count) or ASCII (starting with "solid").
// Identical corner positions are merged into shared vertices (in order of first use); the file's
// facet normals are not kept (the result has no normals).
Mesh parseStl(std::span<const std::uint8_t> bytes);

}  // namespace marzipan
