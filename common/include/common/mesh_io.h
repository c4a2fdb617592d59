// Reading and writing triangle meshes: OBJ, STL (ASCII and binary), PLY (ASCII, binary little and
// big endian, gzip-compressed .ply.gz) and OFF in; STL, OBJ, PLY, OFF and 3MF out.
//
// Every reader validates as it goes: a malformed, truncated, empty, NaN/Inf-containing or
// out-of-range-index file gives kInvalidArgument with "FILE:LINE: what was expected" (or the byte
// offset / element index for binary files), never a crash, a hang or an allocation sized by an
// untrusted header. Polygons with more than three corners are fan-triangulated.
#pragma once

#include <cstddef>
#include <filesystem>
#include <span>
#include <string_view>

#include "common/mesh.h"
#include "common/status.h"
#include "common/units.h"

namespace hc {

enum class MeshFormat { kObj, kStl, kPly, kOff, k3mf };

std::string_view to_string(MeshFormat format);

// The format named by the file's extension (case-insensitive; ".ply.gz" is PLY).
Result<MeshFormat> mesh_format_from_path(const std::filesystem::path& path);

struct MeshReadOptions {
  // STL stores each triangle's corners separately; merge corners with bit-identical coordinates
  // (what every slicer does). Turn off to see the raw triangle soup.
  bool weld_stl_vertices = true;
  // Refuse files that declare more vertices or faces than this (guards memory against hostile
  // headers on top of the size checks against the actual file length).
  std::size_t max_elements = std::size_t{1} << 28;
};

// Reads a mesh, choosing the reader by extension. "-" is not accepted: meshes need a format.
Result<TriangleMesh> read_mesh(const std::filesystem::path& path,
                               const MeshReadOptions& options = {});

// Parses a mesh held in memory. `name` is used in error messages. For PLY the bytes may be gzip.
Result<TriangleMesh> parse_mesh(std::string_view bytes, MeshFormat format, std::string_view name,
                                const MeshReadOptions& options = {});

struct MeshWriteOptions {
  bool binary = true;  // STL and PLY: binary (little endian) or ASCII
  units::LengthUnit unit = units::LengthUnit::kMillimetre;  // 3MF <model unit="...">
};

// Writes a mesh, choosing the writer by extension (".ply.gz" writes gzip). Atomic: on failure no
// file (and no partial file) is left at `path`.
Status write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh,
                  const MeshWriteOptions& options = {});

// Serialises to bytes (what write_mesh writes).
Result<std::string> format_mesh(const TriangleMesh& mesh, MeshFormat format,
                                const MeshWriteOptions& options = {});

// 3MF with several objects, each its own <object> with its name and, when given, a base material
// (one <basematerials> group holding every distinct material, with its display colour). This is
// what multi-material printers' slicers read as "one material per part".
Status write_3mf(const std::filesystem::path& path, std::span<const MeshPart> parts,
                 units::LengthUnit unit = units::LengthUnit::kMillimetre);

}  // namespace hc
