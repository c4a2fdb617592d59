// Internal to hardcopy_fabrication: the CGAL-backed geometry behind mesh_check and mesh_repair.
// This header names no CGAL type, so fabrication/src/*.cpp include it without parsing CGAL; the
// implementation in cgal_mesh_ops.cpp is the only place CGAL is compiled. Every function catches
// what CGAL throws and returns it as a Status.
#pragma once

#include <cstdint>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"

namespace hc::fabrication::cgal_ops {

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

}  // namespace hc::fabrication::cgal_ops
