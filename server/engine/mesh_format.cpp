#include "mesh_format.hpp"

#include <fstream>
#include <limits>

#include "errors.hpp"

namespace marzipan {

std::optional<MeshFormat> meshFormatFromName(std::string_view name) {
  if (name == "stl") return MeshFormat::Stl;
  if (name == "obj") return MeshFormat::Obj;
  if (name == "ply") return MeshFormat::Ply;
  if (name == "glb") return MeshFormat::Glb;
  return std::nullopt;
}

void requireExportable(const Mesh& m) {
  if (m.positions.size() % 3 != 0 || m.indices.size() % 3 != 0)
    throw EngineError(ErrorKind::InvalidArgument, "mesh", "positions and indices must come in threes");
  if (!m.normals.empty() && m.normals.size() != m.positions.size())
    throw EngineError(ErrorKind::InvalidArgument, "mesh", "normals must be empty or one per vertex");
  if (!m.colors.empty() && m.colors.size() != m.positions.size())
    throw EngineError(ErrorKind::InvalidArgument, "mesh", "colours must be empty or one per vertex");
  for (const std::uint32_t i : m.indices)
    if (i >= m.vertexCount()) throw EngineError(ErrorKind::InvalidArgument, "mesh", "vertex index out of range");
  if (m.triangleCount() > std::numeric_limits<std::uint32_t>::max())
    throw EngineError(ErrorKind::TooLarge, "mesh", "more than 2^32 - 1 triangles");
}

void writeFile(const std::string& path, std::span<const std::uint8_t> bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (f) f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!f) throw EngineError(ErrorKind::InvalidArgument, "path", "cannot write " + path);
}

void writeFile(const std::string& path, std::string_view text) {
  writeFile(path, std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

}  // namespace marzipan
