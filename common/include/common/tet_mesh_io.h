// Tetrahedral mesh files: TetGen's .node/.ele (read and write) and VTK's XML UnstructuredGrid .vtu
// (write, for ParaView).
//
// TetGen format (https://wias-berlin.de/software/tetgen/fformats.html):
//   .node: "<#points> <dim=3> <#attributes> <#boundary markers 0|1>" then per point
//          "<index> <x> <y> <z> [attributes...] [marker]"
//   .ele:  "<#tets> <nodes per tet=4> <#region attributes>" then per tet
//          "<index> <n0> <n1> <n2> <n3> [attributes...]"
// '#' starts a comment anywhere; blank lines are skipped. Numbering starts at 0 or 1 (whatever the
// first point's index is) and must be consecutive. The first region attribute becomes
// TetMesh::tet_regions (it must be an integer value); further region attributes are refused.
//
// The reader checks every header count against the bytes that follow before allocating, every
// index against the node count and every value for finiteness, and reports "FILE:LINE: what" on
// error. Tets are returned positively oriented (two nodes swapped where the file had the other
// orientation, as TetGen itself writes); degenerate (zero-volume) tets are refused.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "common/tet_mesh.h"

namespace hc {

struct TetMeshReadOptions {
  // Refuse files declaring more points or tets than this (memory guard on top of the byte checks).
  std::size_t max_elements = std::size_t{1} << 27;
};

// Reads BASE.node and BASE.ele. `path` may be BASE, BASE.node or BASE.ele.
Result<TetMesh> read_tetgen(const std::filesystem::path& path,
                            const TetMeshReadOptions& options = {});

// Parses the two files held in memory; the names are used in error messages.
Result<TetMesh> parse_tetgen(std::string_view node_bytes, std::string_view ele_bytes,
                             std::string_view node_name, std::string_view ele_name,
                             const TetMeshReadOptions& options = {});

// Only the .node part (points, attributes, markers): e.g. TetGen's input point sets.
Result<TetMesh> parse_tetgen_node(std::string_view node_bytes, std::string_view node_name,
                                  const TetMeshReadOptions& options = {});

// The text of BASE.node and BASE.ele (1-based numbering, as TetGen writes; markers, attributes and
// regions included when the mesh has them). Fails when the mesh is not writable (non-finite
// coordinate, index out of range, attribute sizes not matching).
Result<std::string> format_tetgen_node(const TetMesh& mesh);
Result<std::string> format_tetgen_ele(const TetMesh& mesh);

// Writes BASE.node and BASE.ele, each atomically; when the second write fails the first file is
// removed again, so no half pair is left.
Status write_tetgen(const std::filesystem::path& base, const TetMesh& mesh);

// A named data array on the points or the cells of a .vtu: `components` values per point/cell
// (1 scalar, 3 vector, 9 tensor), row-major (values[i * components + c]).
struct VtuArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
};

struct VtuData {
  std::vector<VtuArray> point_data;  // e.g. "displacement_m" (3), "force_n" (3)
  std::vector<VtuArray> cell_data;   // e.g. "youngs_pa" (1), "poisson" (1)
  // Write the mesh's tet_regions as cell data "region" and node_markers as point data "marker".
  bool include_regions_and_markers = true;
  // Positions written instead of the rest positions (#N by 3), e.g. the deformed shape; empty =
  // rest positions.
  MatrixX3d positions;
};

// VTK XML UnstructuredGrid, ASCII, one VTK_TETRA (type 10) per tet. Fails with kInvalidArgument
// when an array's size is not components × count, a name is empty or repeated, or a value is not
// finite.
Result<std::string> format_vtu(const TetMesh& mesh, const VtuData& data = {});
Status write_vtu(const std::filesystem::path& path, const TetMesh& mesh, const VtuData& data = {});

}  // namespace hc
