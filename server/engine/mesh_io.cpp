#include "mesh_io.hpp"

#include <string>
#include <string_view>

#include "errors.hpp"
#include "gltf.hpp"

namespace marzipan {

std::vector<std::uint8_t> exportMesh(const Mesh& m, MeshFormat format) {
  switch (format) {
    case MeshFormat::Stl:
      return exportStl(m);
    case MeshFormat::Obj: {
      const std::string s = exportObj(m);
      return {s.begin(), s.end()};
    }
    case MeshFormat::Ply:
      return exportPly(m);
    case MeshFormat::Glb:
      return exportGlb(m);
  }
  throw EngineError(ErrorKind::InvalidArgument, "format", "unknown mesh format");
}

Mesh parseMesh(std::span<const std::uint8_t> bytes, MeshFormat format) {
  switch (format) {
    case MeshFormat::Stl:
      return parseStl(bytes);
    case MeshFormat::Obj:
      return parseObj(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
    case MeshFormat::Ply:
      return parsePly(bytes);
    case MeshFormat::Glb:
      return parseGlb(bytes);
  }
  throw EngineError(ErrorKind::InvalidArgument, "format", "unknown mesh format");
}

}  // namespace marzipan
