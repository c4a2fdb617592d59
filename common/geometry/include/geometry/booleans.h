// Boolean operations on closed triangle meshes by CGAL's corefinement, computed with exact
// constructions (Epeck) and rounded to doubles at the end. Rounding can, in rare configurations,
// fold a sliver over a neighbour; the result is therefore checked and the summary says so.
#pragma once

#include <cstdint>
#include <string>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::geometry {

enum class BooleanOperation { kUnion, kDifference, kIntersection };

// "union", "difference", "intersection".
const char* to_string(BooleanOperation op);
Result<BooleanOperation> parse_boolean_operation(const std::string& name);

struct BooleanSummary {
  // Pairs of triangles of the rounded result that intersect other than in a shared edge or
  // vertex (0 for a valid solid). Corefinement is exact; only the rounding to doubles can add them.
  std::int64_t self_intersecting_pairs_after_rounding = 0;
  bool closed = false;  // every edge of the result has two faces
  double time_s = 0.0;
};

// Computes `a op b` (difference: a minus b). Both inputs must be closed, manifold, consistently
// oriented triangle meshes that bound a volume and do not self-intersect; each failed precondition
// is a kInvalidArgument naming the input ("first"/"second") and the defect. Coplanar faces,
// touching surfaces and shared edges are handled exactly. An empty result (e.g. disjoint inputs
// intersected) is a mesh with no triangles. kInternal when CGAL fails.
Result<TriangleMesh> corefine_boolean(const TriangleMesh& a, const TriangleMesh& b,
                                      BooleanOperation op, BooleanSummary* summary = nullptr);

}  // namespace hc::geometry
