// CGAL corefinement behind geometry/booleans.h and geometry/csg_sequence.h: one translation unit,
// so CGAL's exact-kernel corefinement is compiled once (the two files took 75 and 117 s apart).
#include "geometry/booleans.h"
#include "geometry/csg_sequence.h"

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <chrono>

#include "cgal_support.h"
#include "geometry/mesh_ops.h"

namespace hc::geometry {
namespace {

namespace PMP = CGAL::Polygon_mesh_processing;
using ExactKernel = CGAL::Exact_predicates_exact_constructions_kernel;
using ExactMesh = CGAL::Surface_mesh<ExactKernel::Point_3>;

Result<ExactMesh> checked_input(const TriangleMesh& mesh, const char* which) {
  const std::string what = fmt::format("boolean: the {} mesh", which);
  HC_ASSIGN_OR_RETURN(ExactMesh sm, internal::to_surface_mesh<ExactKernel::Point_3>(mesh, what));
  if (sm.is_empty()) return invalid_argument(what + " is empty");
  if (!CGAL::is_closed(sm)) return invalid_argument(what + " is not closed (it has boundary edges)");
  if (PMP::does_self_intersect(sm)) return invalid_argument(what + " intersects itself");
  if (!PMP::does_bound_a_volume(sm)) {
    return invalid_argument(what + " does not bound a volume (nested shells wrongly oriented)");
  }
  // CGAL takes an inward-oriented surface as bounding the unbounded complement; a printed part
  // is never that, so say so rather than compute with the complement. The volume is exact.
  if (PMP::volume(sm) < 0) return invalid_argument(what + " is inward oriented (negative volume)");
  return sm;
}

Result<ExactMesh> exact_operand(const TriangleMesh& mesh, const std::string& what, bool check) {
  HC_ASSIGN_OR_RETURN(ExactMesh sm, internal::to_surface_mesh<ExactKernel::Point_3>(mesh, what));
  if (!check) return sm;
  if (sm.is_empty()) return invalid_argument(what + " is empty");
  if (!CGAL::is_closed(sm)) return invalid_argument(what + " is not closed");
  if (PMP::does_self_intersect(sm)) return invalid_argument(what + " intersects itself");
  if (!PMP::does_bound_a_volume(sm) || PMP::volume(sm) < 0)
    return invalid_argument(what + " does not bound a positive volume");
  return sm;
}

// CGAL's corefinement for `op` (`out` may be `a`); false when the result cannot be made manifold.
bool corefine(BooleanOperation op, ExactMesh& a, ExactMesh& b, ExactMesh& out) {
  switch (op) {
    case BooleanOperation::kUnion: return PMP::corefine_and_compute_union(a, b, out);
    case BooleanOperation::kDifference: return PMP::corefine_and_compute_difference(a, b, out);
    case BooleanOperation::kIntersection: return PMP::corefine_and_compute_intersection(a, b, out);
  }
  return false;
}

// Self-intersecting triangle pairs of a result once its exact coordinates are rounded to doubles.
Result<std::int64_t> pairs_after_rounding(const TriangleMesh& result) {
  if (result.num_triangles() == 0) return std::int64_t{0};
  SelfIntersectionQuery query;
  query.triangles.resize(static_cast<std::size_t>(result.num_triangles()));
  for (std::size_t t = 0; t < query.triangles.size(); ++t)
    query.triangles[t] = static_cast<std::int32_t>(t);
  query.is_polygon_mesh = true;
  HC_ASSIGN_OR_RETURN(const SelfIntersectionCount count,
                      count_self_intersecting_pairs(result, query));
  return count.pairs;
}

}  // namespace

const char* to_string(BooleanOperation op) {
  switch (op) {
    case BooleanOperation::kUnion: return "union";
    case BooleanOperation::kDifference: return "difference";
    case BooleanOperation::kIntersection: return "intersection";
  }
  return "unknown";
}

Result<BooleanOperation> parse_boolean_operation(const std::string& name) {
  if (name == "union") return BooleanOperation::kUnion;
  if (name == "difference") return BooleanOperation::kDifference;
  if (name == "intersection") return BooleanOperation::kIntersection;
  return invalid_argument(fmt::format(
      "unknown boolean operation '{}' (expected union, difference or intersection)", name));
}

Result<TriangleMesh> corefine_boolean(const TriangleMesh& a, const TriangleMesh& b,
                                      BooleanOperation op, BooleanSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  return internal::guarded<TriangleMesh>("boolean", [&]() -> Result<TriangleMesh> {
    HC_ASSIGN_OR_RETURN(ExactMesh ma, checked_input(a, "first"));
    HC_ASSIGN_OR_RETURN(ExactMesh mb, checked_input(b, "second"));
    ExactMesh out;
    if (!corefine(op, ma, mb, out)) {
      return internal_error(fmt::format(
          "boolean {}: CGAL could not build the result as a manifold mesh (the inputs touch "
          "along a non-manifold curve)",
          to_string(op)));
    }
    TriangleMesh result = internal::to_triangle_mesh(out);
    if (summary != nullptr) {
      summary->closed = CGAL::is_closed(out);
      HC_ASSIGN_OR_RETURN(summary->self_intersecting_pairs_after_rounding,
                          pairs_after_rounding(result));
      summary->time_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return result;
  });
}

Result<TriangleMesh> csg_sequence(const TriangleMesh& base, const std::vector<CsgStep>& steps,
                                  const CsgOptions& options, CsgSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  ProgressTask task(options.progress, "booleans", steps.size());
  return internal::guarded<TriangleMesh>("csg", [&]() -> Result<TriangleMesh> {
    HC_ASSIGN_OR_RETURN(ExactMesh acc, exact_operand(base, "csg: the base", options.check_operands));
    for (const CsgStep& step : steps) {
      const std::string what = fmt::format("csg: {} '{}'", to_string(step.op), step.name);
      HC_ASSIGN_OR_RETURN(ExactMesh operand,
                          exact_operand(step.operand, what, options.check_operands));
      if (!corefine(step.op, acc, operand, acc))
        return internal_error(what + ": CGAL could not make the result a manifold mesh");
      task.advance();
    }
    TriangleMesh result = internal::to_triangle_mesh(acc);
    if (summary != nullptr) {
      summary->steps = static_cast<int>(steps.size());
      summary->closed = CGAL::is_closed(acc);
      summary->self_intersecting_pairs_after_rounding = 0;
      if (options.count_self_intersections) {
        HC_ASSIGN_OR_RETURN(summary->self_intersecting_pairs_after_rounding,
                            pairs_after_rounding(result));
      }
      summary->time_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return result;
  });
}

}  // namespace hc::geometry
