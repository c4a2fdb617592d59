// hardcopy_geometry: the CGAL-backed mesh operations every room may use (printability checks and
// repair today). This header names no CGAL type, so its users compile without parsing CGAL; the
// sources of common/geometry/src/ are the only translation units of the project that include
// CGAL. Every function catches what CGAL throws and returns it as a Status.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"

namespace hc::geometry {

// One CGAL step of the self-intersection stage, in the order tried:
//   "cap_flips"     CGAL::PMP::experimental::remove_almost_degenerate_faces on the intersecting
//                   triangles: flips the longest edge of caps (an angle over 160 degrees), which
//                   moves no vertex. A near-flat sliver folded over its neighbours is such a cap.
//   "local_removal" CGAL::PMP::experimental::remove_self_intersections (genus preserved): smooths
//                   the region around the intersections, or removes it and fills the hole.
//   "autorefine"    CGAL::PMP::experimental::autorefine_and_remove_self_intersections, closed
//                   meshes only: splits faces along their intersections and removes what lies
//                   inside the solid (the union of overlapping parts).
// A step's result is kept only if it is a valid triangle mesh, closed if its input was, with
// fewer intersecting pairs, within the allowed deviation (one-sided for autorefine, whose result
// must lie on its input) and, for autorefine, bounding a positive volume.
struct SelfIntersectionStep {
  std::string method;
  bool kept = false;  // its result replaced the mesh
  std::int64_t pairs_before = 0;
  std::int64_t pairs_after = -1;  // -1: not counted (CGAL threw, or the result was invalid)
  // Hausdorff distance between the step's result and its input, in the mesh's unit, as CGAL's
  // bounded-error algorithm measures it: within deviation_error of the true distance (a tenth of
  // the allowed deviation). -1: not measured.
  double deviation = -1.0;
  double deviation_error = 0.0;
  double time_s = 0.0;
  std::string note;  // why the result was not kept, or what CGAL reported
};

// For each triangle of `mesh`, 1 when its three corners are exactly collinear and 0 otherwise
// (CGAL::collinear on Epick: a filtered predicate, exact for double input). Corners at the same
// position, or the same index twice, are collinear. Precondition: indices in range, referenced
// coordinates finite (check_mesh validates both first).
Result<std::vector<std::uint8_t>> collinear_triangles(const TriangleMesh& mesh);

// Units count_self_intersecting_pairs advances its ProgressTask by: building the CGAL mesh, the
// box-intersection sweep with its exact tests, and turning CGAL's pairs into the count.
inline constexpr std::uint64_t kSelfIntersectionSteps = 3;

struct SelfIntersectionQuery {
  // Rows of mesh.triangles to test against each other; each with three distinct corners.
  std::vector<std::int32_t> triangles;
  // True when `triangles` form a manifold, consistently oriented surface (each edge used at most
  // twice and then in opposite directions, one fan per vertex). They then become a
  // CGAL::Surface_mesh as they are; otherwise they go through orient_polygon_soup first.
  bool is_polygon_mesh = false;
  bool parallel = true;              // CGAL::Parallel_if_available_tag (TBB) or Sequential_tag
  std::uint64_t max_pairs = 0;       // stop after this many pairs; 0: count all
  ProgressTask* progress = nullptr;  // advanced by kSelfIntersectionSteps units in total
};

struct SelfIntersectionCount {
  std::int64_t pairs = 0;  // pairs of triangles that intersect other than in a shared edge/vertex
  bool limit_reached = false;
  // Vertices orient_polygon_soup had to duplicate to make the input a Surface_mesh (soup path).
  std::int64_t duplicated_vertices = 0;
};

// Counts the pairs of `query.triangles` that intersect in more than the vertex or edge they share
// (CGAL::Polygon_mesh_processing::self_intersections). Collinear triangles take no part: CGAL
// would report each as intersecting itself, and check_mesh counts them as degenerate instead.
Result<SelfIntersectionCount> count_self_intersecting_pairs(const TriangleMesh& mesh,
                                                            const SelfIntersectionQuery& query);

struct SoupRepairOptions {
  bool orient = true;             // consistent orientation, then outward (bounding a volume)
  bool remove_collinear = true;   // remove collinear triangles without opening the surface
  bool remove_duplicates = true;  // remove triangles that removing collinear ones duplicated
};

struct SoupRepairStats {
  std::int64_t split_vertices = 0;    // points orient_polygon_soup duplicated
  std::int64_t collinear_before = 0;  // collinear triangles before removal
  std::int64_t collinear_after = 0;   // ... and after (CGAL may not manage all of them)
  // Triangles that removing collinear ones left with a repeated corner, or duplicated.
  std::int64_t degenerate_removed_later = 0;
  std::int64_t duplicates_removed_later = 0;
  bool polygon_mesh = false;             // the soup became a CGAL::Surface_mesh
  bool bounds_volume = false;            // oriented by orient_to_bound_a_volume (nesting respected)
  std::int64_t reversed_components = 0;  // closed components turned outward one by one instead
};

// Repairs a triangle soup in place: `soup` has distinct vertex positions and triangles with three
// distinct corners. With options.orient the orientation is made consistent
// (orient_polygon_soup, duplicating points where the surface is non-manifold) and closed surfaces
// are turned outward (orient_to_bound_a_volume when the result is closed and free of
// self-intersections, otherwise each closed component to positive volume). With
// options.remove_collinear, collinear triangles are removed by CGAL's edge flips and collapses,
// which keep a closed surface closed (duplicates these create go with options.remove_duplicates,
// and the orientation is then redone). Vertex positions are never moved; vertices may be appended
// (duplicates) or left unreferenced.
Status repair_triangle_soup(const SoupRepairOptions& options, TriangleMesh* soup,
                            SoupRepairStats* stats);

struct ResolveOptions {
  // Largest change of the surface a step may make, in the mesh's unit (> 0). The local steps (cap
  // flips, local removal) are kept only if the symmetric Hausdorff distance between their result
  // and their input is at most this; autorefine only if every point of its result is within this
  // of its input (one-sided: removing the parts inside the solid is what it is for).
  double max_deviation = 0.0;
  bool parallel = true;              // self-intersection sweeps on all cores (TBB)
  ProgressTask* progress = nullptr;  // advanced once per step of kResolveSteps
};

// Units resolve_self_intersections advances its ProgressTask by: one per step.
inline constexpr std::uint64_t kResolveSteps = 3;

// Tries to remove the self-intersections of `mesh`, a manifold, consistently oriented triangle
// mesh (no repeated corners, no unreferenced vertices), with CGAL, one step after the other while
// intersecting pairs remain:
//   1. "cap_flips": PMP::experimental::remove_almost_degenerate_faces on the intersecting faces
//      only, flipping the longest edge of caps (an angle over 160 degrees) and collapsing nothing;
//      a sliver folded over its neighbours is such a cap, and the flip moves no vertex.
//   2. "local_removal": PMP::experimental::remove_self_intersections (smoothing, or removing the
//      faces around the intersections and filling the hole), preserving the genus.
//   3. "autorefine": PMP::experimental::autorefine_and_remove_self_intersections, only on a
//      closed mesh: splits the faces along their intersections and removes the inner parts.
// Each step works on a copy; its result replaces `mesh` only if it is a valid triangle mesh, still
// closed if its input was, has fewer intersecting pairs (collinear faces not counted, as in
// check_mesh), stays within options.max_deviation and, for autorefine, bounds a positive volume.
// What each step did is appended to `steps` (a step CGAL throws in is recorded, not returned).
// Fails (kInvalidArgument) when `mesh` is not such a mesh, leaving it untouched.
Status resolve_self_intersections(const ResolveOptions& options, TriangleMesh* mesh,
                                  std::vector<SelfIntersectionStep>* steps);

}  // namespace hc::geometry
