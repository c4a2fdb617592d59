// Mesh file I/O: format dispatch and the helpers every reader and writer shares. The readers are
// hand-written because Debian offers no fast, non-throwing reader for all of OBJ/STL/PLY/OFF.
#include "common/mesh_io.h"

#include <fmt/format.h>
#if defined(__linux__)
#endif

#include <algorithm>
#include <cctype>
#include <string>

#include "common/file_io.h"
#include "mesh_io_internal.h"

namespace hc {
namespace mesh_io {

std::string quote(std::string_view token) {
  constexpr std::size_t kMaxShown = 40;
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < kMaxShown; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f && c != '\'') {
      out.push_back(static_cast<char>(c));
    } else {
      out += fmt::format("\\x{:02x}", c);
    }
  }
  if (token.size() > kMaxShown) out += "...";
  out.push_back('\'');
  return out;
}

Status check_writable(const TriangleMesh& mesh, std::string_view what) {
  const Eigen::Index nv = mesh.num_vertices();
  for (Eigen::Index i = 0; i < nv; ++i) {
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(mesh.vertices(i, k)))
        return invalid_argument(fmt::format("{}: vertex {} has a non-finite coordinate ({})", what,
                                            i, mesh.vertices(i, k)));
    }
  }
  const Eigen::Index nt = mesh.num_triangles();
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(t, k);
      if (v < 0 || v >= nv)
        return invalid_argument(fmt::format(
            "{}: triangle {} refers to vertex {}, expected an index in [0, {})", what, t, v, nv));
    }
  }
  return {};
}

}  // namespace mesh_io

namespace {

bool ends_with_nocase(std::string_view s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  return std::equal(suffix.begin(), suffix.end(),
                    s.end() - static_cast<std::ptrdiff_t>(suffix.size()), [](char a, char b) {
                      return std::tolower(static_cast<unsigned char>(a)) ==
                             std::tolower(static_cast<unsigned char>(b));
                    });
}

bool is_gzip_path(const std::filesystem::path& path) {
  return ends_with_nocase(path.filename().string(), ".gz");
}

}  // namespace

std::string_view to_string(MeshFormat format) {
  switch (format) {
    case MeshFormat::kObj:
      return "obj";
    case MeshFormat::kStl:
      return "stl";
    case MeshFormat::kPly:
      return "ply";
    case MeshFormat::kOff:
      return "off";
    case MeshFormat::k3mf:
      return "3mf";
  }
  return "unknown";
}

Result<MeshFormat> mesh_format_from_path(const std::filesystem::path& path) {
  const std::string name = path.filename().string();
  struct Entry {
    std::string_view suffix;
    MeshFormat format;
  };
  static constexpr Entry kSuffixes[] = {
      {".obj", MeshFormat::kObj},    {".stl", MeshFormat::kStl}, {".ply", MeshFormat::kPly},
      {".ply.gz", MeshFormat::kPly}, {".off", MeshFormat::kOff}, {".3mf", MeshFormat::k3mf},
  };
  for (const auto& e : kSuffixes)
    if (name.size() > e.suffix.size() && ends_with_nocase(name, e.suffix)) return e.format;
  return unsupported(fmt::format(
      "{}: unknown mesh file extension (expected .obj, .stl, .ply, .ply.gz, .off or .3mf)",
      path.string()));
}

Result<TriangleMesh> parse_mesh(std::string_view bytes, MeshFormat format, std::string_view name,
                                const MeshReadOptions& options) {
  if (bytes.empty()) return mesh_io::error_at(name, 0, "empty file, expected a mesh");
  switch (format) {
    case MeshFormat::kObj:
      return mesh_io::parse_obj(bytes, name, options);
    case MeshFormat::kStl:
      return mesh_io::parse_stl(bytes, name, options);
    case MeshFormat::kPly:
      return mesh_io::parse_ply(bytes, name, options);
    case MeshFormat::kOff:
      return mesh_io::parse_off(bytes, name, options);
    case MeshFormat::k3mf:
      return unsupported(
          fmt::format("{}: reading 3MF is not supported (3MF is an output format here)", name));
  }
  return internal_error(fmt::format("{}: unknown MeshFormat value", name));
}

Result<TriangleMesh> read_mesh(const std::filesystem::path& path, const MeshReadOptions& options) {
  if (path == "-")
    return invalid_argument("'-' (standard input) is not accepted: a mesh needs a file extension");
  HC_ASSIGN_OR_RETURN(const MeshFormat format, mesh_format_from_path(path));
  if (format == MeshFormat::k3mf)
    return unsupported(fmt::format(
        "{}: reading 3MF is not supported (3MF is an output format here)", path.string()));
  HC_ASSIGN_OR_RETURN(const std::string bytes, read_file(path));
  return parse_mesh(bytes, format, path.string(), options);
}

Result<std::string> format_mesh(const TriangleMesh& mesh, MeshFormat format,
                                const MeshWriteOptions& options) {
  if (format == MeshFormat::k3mf) {
    const MeshPart part{"mesh", mesh, "", std::nullopt};
    return mesh_io::format_3mf(std::span<const MeshPart>(&part, 1), options.unit);
  }
  HC_RETURN_IF_ERROR(mesh_io::check_writable(mesh, "mesh"));
  switch (format) {
    case MeshFormat::kObj:
      return mesh_io::format_obj(mesh);
    case MeshFormat::kStl:
      return mesh_io::format_stl(mesh, options.binary);
    case MeshFormat::kPly:
      return mesh_io::format_ply(mesh, options.binary);
    case MeshFormat::kOff:
      return mesh_io::format_off(mesh);
    case MeshFormat::k3mf:
      break;
  }
  return internal_error("format_mesh: unknown MeshFormat value");
}

Status write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh,
                  const MeshWriteOptions& options) {
  HC_ASSIGN_OR_RETURN(const MeshFormat format, mesh_format_from_path(path));
  if (format == MeshFormat::k3mf) {
    const MeshPart part{path.stem().string(), mesh, "", std::nullopt};
    return mesh_io::write_3mf_file(path, std::span<const MeshPart>(&part, 1), options.unit);
  }
  auto bytes = format_mesh(mesh, format, options);
  if (!bytes.ok()) return bytes.status().with_context(path.string());
  if (is_gzip_path(path)) {
    HC_ASSIGN_OR_RETURN(const std::string gz, mesh_io::gzip_compress(*bytes));
    return write_file_atomic(path, gz);
  }
  return write_file_atomic(path, *bytes);
}

Status write_3mf(const std::filesystem::path& path, std::span<const MeshPart> parts,
                 units::LengthUnit unit) {
  return mesh_io::write_3mf_file(path, parts, unit);
}

}  // namespace hc
