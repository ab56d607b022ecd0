// Wavefront OBJ files (conventions in mesh_format.hpp).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "mesh_format.hpp"

namespace marzipan {

// OBJ: "v x y z" and, when the mesh has normals, "vn" lines and faces "f a//a b//b c//c"
// (1-based); floats with 9 significant digits, so parsing gives back the same floats. Vertex
// colours, when the mesh has them, as MeshLab writes and reads them: "v x y z r g b" with r, g,
// b the sRGB bytes / 255 in 4 significant digits (255 times them rounds back to the bytes).
std::string exportObj(const Mesh& m);

// OBJ: "v" and "f" statements (polygons are fanned into triangles, negative indices count back
// from the last vertex); normals are kept only when every face uses normal index = vertex index,
// colours only when every "v" has three numbers in 0..1 after x y z (times 255, rounded; a
// fourth number alone is a w and means no colour). Other statements (vt, g, o, s, usemtl, ...)
// are ignored.
Mesh parseObj(std::string_view text);

}  // namespace marzipan
