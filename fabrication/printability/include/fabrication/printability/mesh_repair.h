// Repairs the common defects of meshes headed for a printer: duplicate vertices, degenerate and
// duplicate triangles, inconsistent and inward orientation, and (opt-in) self-intersections. It
// does not fill holes; the summary says whether the result is closed and printable.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "fabrication/printability/mesh_check.h"
#include "geometry/mesh_ops.h"

namespace hc::fabrication {

// Default of MeshRepairOptions::self_intersection_max_deviation: 0.1 mm on a part whose diagonal
// is 100 mm, a quarter of the line width of a common 0.4 mm FDM nozzle, so the printer cannot show
// the change. CGAL's local removal "fixes" candleStand.stl by moving a vertex 3.0 units (Hausdorff
// distance at least 1.38, 1.4e-2 of its 95.7 diagonal); the cap flip that fixes it moves nothing.
inline constexpr double kDefaultSelfIntersectionMaxDeviation = 1e-3;

struct MeshRepairOptions {
  // Vertices closer than this (in the mesh's unit) are merged; 0 merges only identical positions.
  double weld_tolerance = 0.0;
  bool remove_degenerate_triangles = true;
  bool remove_duplicate_triangles = true;
  bool remove_unreferenced_vertices = true;
  // Make orientation consistent, then point every closed component's normals outward (positive
  // volume, respecting nesting: an inner shell of a hollow part points inward).
  bool orient = true;
  // Opt-in last stage: when the steps above leave self-intersecting triangles, try CGAL's
  // experimental repairs (cap flips, local removal, autorefinement; see SelfIntersectionStage).
  // They may move, replace or remove faces around the intersections. Off by default because they
  // change the shape, and because CGAL marks them experimental.
  bool resolve_self_intersections = false;
  // Largest change of the surface the stage may make, as a fraction of the bounding-box diagonal
  // of the mesh it starts from (> 0); a CGAL step that moves the surface further is discarded.
  double self_intersection_max_deviation = kDefaultSelfIntersectionMaxDeviation;
  ProgressReporter* progress = nullptr;

  Status validate() const;
};

// One CGAL step of the self-intersection stage (geometry/mesh_ops.h says what each does).
using geometry::SelfIntersectionStep;

struct SelfIntersectionStage {
  // resolve_self_intersections was on and the earlier steps left intersecting pairs.
  bool attempted = false;
  // Attempted, but no step's result was kept: the mesh is the earlier steps' (a warning, not an
  // error of repair_mesh). `message` says why.
  bool failed = false;
  std::string message;
  std::int64_t pairs_before = 0;  // left by the earlier steps
  std::int64_t pairs_after = 0;   // in the final mesh (= after.self_intersecting_pairs)
  std::vector<SelfIntersectionStep> steps;
  double time_s = 0.0;
};

struct MeshRepairSummary {
  std::int64_t merged_vertices = 0;
  std::int64_t removed_degenerate_triangles = 0;
  std::int64_t removed_duplicate_triangles = 0;
  std::int64_t removed_unreferenced_vertices = 0;
  std::int64_t flipped_triangles = 0;
  // Vertices duplicated so that orientation could be made consistent (non-manifold spots).
  std::int64_t split_non_manifold_vertices = 0;
  // Self-intersecting pairs the stage removed: stage.pairs_before - stage.pairs_after.
  std::int64_t resolved_self_intersecting_pairs = 0;
  SelfIntersectionStage self_intersections;
  MeshCheckReport before;
  MeshCheckReport after;
  bool closed = false;     // after.closed
  bool printable = false;  // after.printable
  double time_s = 0.0;

  // True when the repair changed anything.
  bool changed() const;
};

// Repairs `mesh` in place. Fails (kInvalidArgument) only on invalid options, input indices out of
// range or a non-finite coordinate of a used vertex (kInternal if CGAL fails), leaving `mesh`
// untouched; an input that cannot be made closed is repaired as far as possible and
// summary->closed is false. The self-intersection stage never fails the repair: when CGAL fails
// there, summary->self_intersections says so and the mesh of the earlier steps is returned.
Status repair_mesh(const MeshRepairOptions& options, TriangleMesh* mesh,
                   MeshRepairSummary* summary);

nlohmann::json to_json(const SelfIntersectionStage& stage);
nlohmann::json to_json(const MeshRepairSummary& summary);
std::string to_text(const MeshRepairSummary& summary);

}  // namespace hc::fabrication
