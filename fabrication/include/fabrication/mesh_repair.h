// Repairs the common defects of meshes headed for a printer: duplicate vertices, degenerate and
// duplicate triangles, inconsistent and inward orientation. It does not fill holes or resolve
// self-intersections; the summary says whether the result is closed and printable.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "fabrication/mesh_check.h"

namespace hc::fabrication {

struct MeshRepairOptions {
  // Vertices closer than this (in the mesh's unit) are merged; 0 merges only identical positions.
  double weld_tolerance = 0.0;
  bool remove_degenerate_triangles = true;
  bool remove_duplicate_triangles = true;
  bool remove_unreferenced_vertices = true;
  // Make orientation consistent, then point every closed component's normals outward (positive
  // volume, respecting nesting: an inner shell of a hollow part points inward).
  bool orient = true;
  ProgressReporter* progress = nullptr;

  std::string validate() const;
};

struct MeshRepairSummary {
  std::int64_t merged_vertices = 0;
  std::int64_t removed_degenerate_triangles = 0;
  std::int64_t removed_duplicate_triangles = 0;
  std::int64_t removed_unreferenced_vertices = 0;
  std::int64_t flipped_triangles = 0;
  // Vertices duplicated so that orientation could be made consistent (non-manifold spots).
  std::int64_t split_non_manifold_vertices = 0;
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
// summary->closed is false.
Status repair_mesh(const MeshRepairOptions& options, TriangleMesh* mesh,
                   MeshRepairSummary* summary);

nlohmann::json to_json(const MeshRepairSummary& summary);
std::string to_text(const MeshRepairSummary& summary);

}  // namespace hc::fabrication
