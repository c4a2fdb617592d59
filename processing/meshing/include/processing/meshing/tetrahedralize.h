// Tetrahedral meshing: closed surfaces and TetGen .poly files through TetGen (quality and maximum
// volume controls, region attributes), and structured box specimens (e.g. the thesis's
// 50 × 50 × 25 mm blocks) either as a regular grid of hexahedra split into tetrahedra or as a
// TetGen quality mesh of the box.
//
// Units: whatever the input's are (the CLI scales surfaces to metres first); volumes in those
// units cubed. Every returned TetMesh is positively oriented (common/tet_mesh.h).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/meshing/size_field.h"

namespace hc::meshing {

// A region of the domain (TetGen's region list): the tets of the connected part containing
// `seed` get `attribute` (TetMesh::tet_regions) and, when max_volume > 0, that volume bound.
struct RegionSeed {
  Eigen::Vector3d seed = Eigen::Vector3d::Zero();
  int attribute = 0;
  double max_volume = 0;
};

// The tightest radius-edge bound accepted (see TetrahedralizeOptions::validate).
inline constexpr double kMinRadiusEdgeRatio = 1.1;

struct TetrahedralizeOptions {
  // TetGen 'q': upper bound on the radius-edge ratio of every tet (≥ kMinRadiusEdgeRatio; TetGen's
  // own default is 2.0; 1.414 is its recommended tight bound). 0 disables quality refinement.
  double max_radius_edge_ratio = 2.0;
  // TetGen 'q…/d': lower bound on dihedral angles in degrees (0: TetGen's default).
  double min_dihedral_deg = 0;
  // TetGen 'a': upper bound on every tet's volume (0: none).
  double max_volume = 0;
  // TetGen 'A' (+ 'a' without a number for per-region volumes when any region sets one).
  std::vector<RegionSeed> regions;
  // TetGen's hole list: points inside cavities that are to stay empty.
  std::vector<Eigen::Vector3d> holes;
  // TetGen 'S': at most this many points added to the input (0: no limit). TetGen stops refining
  // when they are used up, so this bounds the element count (and memory) whatever q and a ask;
  // a result with nodes - input_vertices == max_steiner_points did not meet them.
  long max_steiner_points = 0;

  // Mesh sizing function (TetGen 'm' with a background mesh, size_field.h): the desired edge length
  // near a point (input units), e.g. fine where a probe will touch and coarse far from it. TetGen
  // splits the boundary and the volume until edges are about this long (measured on boxes with a
  // uniform size: mean edge 1.3 x the size, boundary edges 1.2 x). Empty: no sizing function.
  // Must return finite values > 0 over the input's bounding box.
  EdgeSizeFunction edge_size;

  // Fails with kInvalidArgument explaining the bad value.
  Status validate() const;
  // The TetGen switches these options give, e.g. "pq1.414a0.1Q" (always 'p' and quiet 'Q').
  std::string tetgen_switches() const;
};

struct TetrahedralizeSummary {
  std::string switches;  // what TetGen was run with
  Eigen::Index input_vertices = 0;
  Eigen::Index input_facets = 0;
  Eigen::Index nodes = 0;
  Eigen::Index tets = 0;
  Eigen::Index boundary_faces = 0;  // triangles on the domain boundary (TetGen's trifaces)
  double volume = 0;                // sum of tet volumes
  double min_tet_volume = 0;
  double max_tet_volume = 0;
  double time_s = 0;
};

// Tetrahedralizes the region bounded by a closed, consistently oriented triangle surface. Node
// markers: 1 on the boundary, 0 inside. Fails with kInvalidArgument on an empty surface, bad
// indices, non-finite coordinates, an open / non-manifold / misoriented or self-intersecting
// surface (checked here, before TetGen: TetGen 1.5.0 frees its memory twice on its own error
// path) or a surface TetGen rejects otherwise (its reason is quoted), kFailedPrecondition when
// TetGen produces no tets.
Result<TetMesh> tetrahedralize(const TriangleMesh& surface, const TetrahedralizeOptions& options,
                               TetrahedralizeSummary* summary = nullptr);

// A piecewise linear complex as in TetGen's .poly format: points, polygonal facets (each one or
// more polygons, with optional facet holes and a boundary marker), volume holes and regions.
struct Plc {
  struct Facet {
    std::vector<std::vector<int>> polygons;  // zero-based point indices
    std::vector<Eigen::Vector3d> holes;      // points in holes of this facet
    int marker = 0;
  };
  MatrixX3d points;  // #P by 3
  std::vector<Facet> facets;
  std::vector<Eigen::Vector3d> holes;
  std::vector<RegionSeed> regions;
};

// Parses TetGen's .poly format (https://wias-berlin.de/software/tetgen/fformats.poly.html; points
// inline, 0- or 1-based). Hand-written because TetGen's own loader (tetgenio::load_poly) crashes on
// malformed files. Every count is checked against the bytes that follow, every index against the
// point count; errors are kInvalidArgument "NAME:LINE: what".
Result<Plc> parse_poly(std::string_view bytes, std::string_view name);
Result<Plc> read_poly(const std::filesystem::path& path);

// Tetrahedralizes a PLC with `options` (its own holes and regions are used; options' regions and
// holes are added). Region attributes become tet_regions when `region_attributes` is set or
// options.regions is non-empty.
Result<TetMesh> tetrahedralize(const Plc& plc, const TetrahedralizeOptions& options,
                               TetrahedralizeSummary* summary = nullptr,
                               bool region_attributes = false);

// read_poly + tetrahedralize.
Result<TetMesh> tetrahedralize_poly(const std::filesystem::path& path,
                                    const TetrahedralizeOptions& options,
                                    TetrahedralizeSummary* summary = nullptr,
                                    bool region_attributes = false);

// ---- Box specimens ----

// Node markers of box specimens.
inline constexpr int kMarkerInterior = 0;
inline constexpr int kMarkerBottom = 1;  // z = 0 face (where a specimen is fixed)
inline constexpr int kMarkerTop = 2;     // z = size.z face (where it is probed)
inline constexpr int kMarkerSide = 3;    // the four side faces (not top or bottom)

// A box [0, size.x] × [0, size.y] × [0, size.z] as cells.x × cells.y × cells.z hexahedra, each
// split into 6 tetrahedra around its main diagonal (Kuhn/Freudenthal: conforming across cells, all
// the same volume). Node markers as above (bottom wins over side, top over side).
Result<TetMesh> structured_box(const Eigen::Vector3d& size, const Eigen::Vector3i& cells);

// The box [0, size.x] × [0, size.y] × [0, size.z] meshed by TetGen with `options` (12-triangle
// surface in, quality/volume refinement adds interior and surface points), markers as above.
Result<TetMesh> box_tet_mesh(const Eigen::Vector3d& size, const TetrahedralizeOptions& options,
                             TetrahedralizeSummary* summary = nullptr);

// The 12-triangle outward-oriented surface of the box [0, size.x] × [0, size.y] × [0, size.z].
TriangleMesh box_surface(const Eigen::Vector3d& size);

// Indices of the nodes with marker `marker` (e.g. kMarkerBottom: the nodes to fix).
std::vector<int> nodes_with_marker(const TetMesh& mesh, int marker);

// Indices of the nodes whose coordinate `axis` (0 x, 1 y, 2 z) is within `tolerance` of `value`.
std::vector<int> nodes_on_plane(const TetMesh& mesh, int axis, double value, double tolerance);

// Total volume (sum of signed tet volumes).
double total_volume(const TetMesh& mesh);

}  // namespace hc::meshing
