// "Is this mesh printable?" — the check every fabrication lab runs before printing anything.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"

namespace hc::fabrication {

struct MeshCheckOptions {
  // The self-intersection test is the expensive stage (CGAL box intersection + exact predicates);
  // it can be turned off for a quick topological check (then `printable` is not decided: false).
  bool check_self_intersections = true;
  // Stop counting self-intersecting pairs after this many (0: count all).
  std::uint64_t max_self_intersecting_pairs = 0;
  // Run the self-intersection sweep on all cores (CGAL::Parallel_if_available_tag, TBB); false
  // runs it sequentially (for comparison, or to leave the cores to other work).
  bool parallel = true;
  ProgressReporter* progress = nullptr;

  // OK when valid; otherwise says what is wrong.
  Status validate() const;
};

// What check_mesh found. Lengths, areas and volumes are in the mesh's own unit (cubed for volume).
struct MeshCheckReport {
  std::int64_t vertices = 0;
  std::int64_t triangles = 0;
  std::int64_t unreferenced_vertices = 0;  // vertices no triangle uses
  std::int64_t components = 0;             // connected through shared edges
  std::int64_t edges = 0;                  // distinct undirected edges
  std::int64_t boundary_edges = 0;         // edges with one incident triangle
  std::int64_t non_manifold_edges = 0;     // edges with three or more incident triangles
  std::int64_t non_manifold_vertices = 0;  // vertices whose triangles form more than one fan
  std::int64_t misoriented_edges = 0;      // manifold edges traversed in the same direction twice
  bool consistently_oriented = false;
  std::int64_t degenerate_triangles = 0;  // repeated corner or collinear corners (exact predicate)
  std::int64_t duplicate_triangles = 0;   // same three vertices as an earlier triangle
  bool self_intersections_checked = false;
  std::int64_t self_intersecting_pairs = 0;
  bool self_intersection_limit_reached = false;  // counting stopped at max_self_intersecting_pairs
  double area = 0.0;
  double volume = 0.0;                // signed; meaningful when closed
  std::optional<std::int64_t> genus;  // when closed and manifold: sum over components
  Eigen::AlignedBox3d bounding_box;   // of the vertices triangles use; empty if none
  bool closed = false;                // no boundary edges (and not empty)
  bool manifold = false;              // no non-manifold edges or vertices
  bool printable = false;
  std::vector<std::string> problems;  // why not printable, one short sentence each
  std::vector<std::string> warnings;  // defects that do not stop printing (degenerate,
                                      // duplicate triangles, unreferenced vertices)
  std::vector<std::pair<std::string, double>> stage_seconds;  // wall time of each stage
};

// Checks a mesh. Fails only on invalid options, indices out of range or a non-finite coordinate of
// a vertex some triangle uses (kInvalidArgument), or when CGAL fails (kInternal); a mesh that is
// not printable is a successful check whose report says so.
Result<MeshCheckReport> check_mesh(const TriangleMesh& mesh, const MeshCheckOptions& options = {});

// The report as JSON, with at least: vertices, triangles, components, boundary_edges,
// non_manifold_edges, non_manifold_vertices, consistently_oriented, self_intersecting_pairs,
// volume, genus (null when not closed), printable; plus the other fields above and `bounding_box`
// {min,max}, `problems`, `stage_seconds`.
nlohmann::json to_json(const MeshCheckReport& report);

// A human-readable multi-line report (what `hardcopy mesh check` prints without --json).
std::string to_text(const MeshCheckReport& report);

}  // namespace hc::fabrication
