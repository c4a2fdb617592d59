// Offsets and booleans on unions of medial balls (thesis Sec. 7.5), in 2-D (polygons) and 3-D
// (closed triangle meshes). Offsetting grows the interior balls and shrinks the exterior ones by
// the distance (or the reverse), dropping balls whose radius would fall to zero or below, then
// extracts the crust. A boolean samples both inputs (with their intersection points in the corner
// pools and their intersection edges in the edge pools), keeps the samples of each input that lie
// on the result's boundary, builds the medial balls of the union of those samples and labels each
// ball by the operation applied to the two inputs' inside tests at its centre. Nothing in it
// depends on the inputs' faces meeting in general position: touching faces, coplanar overlaps and
// shared edges only change which samples are kept, never the validity of the crust.
#pragma once

#include <cstdint>
#include <string>

#include "common/mesh.h"
#include "common/status.h"
#include "fabrication/abstraction/medial_balls.h"
#include "fabrication/abstraction/polygon.h"
#include "fabrication/abstraction/power_crust.h"
#include "fabrication/abstraction/sampling.h"
#include "geometry/booleans.h"

namespace hc::abstraction {

struct ShapeOptions {
  SamplingOptions sampling;
  MedialOptions medial;
  Status validate() const;
};

// The common summary of every operation (the fields `--json` prints).
struct OperationSummary {
  std::size_t samples = 0;
  std::size_t balls = 0;
  std::size_t intersection_points = 0;  // booleans
  std::size_t intrusions_closed = 0;    // abstraction
  std::size_t intrusions_kept = 0;
  SamplingSummary sampling;
  MedialSummary medial;
  CrustSummary crust;
  // Booleans: the medial-ball crust was not a valid solid and the result is CGAL's exact
  // corefinement of the same inputs instead (`fallback_reason` says what the crust had).
  bool exact_fallback = false;
  std::string fallback_reason;
  double time_s = 0.0;
};

enum class BooleanOp { kUnion, kDifference, kIntersection };
const char* to_string(BooleanOp op);
Result<BooleanOp> parse_boolean_op(std::string_view name);
// The same operation for geometry::corefine_boolean (the exact boolean).
geometry::BooleanOperation to_geometry(BooleanOp op);

// Medial balls of a polygon / closed mesh (sampled, labelled by the even-odd / ray test).
Result<Balls2> polygon_balls(const Polygon2& polygon, const ShapeOptions& options,
                             OperationSummary* summary);
Result<Balls3> mesh_balls(const TriangleMesh& mesh, const ShapeOptions& options,
                          OperationSummary* summary);

// The crust of the same balls: a reconstruction of the input.
Result<Polygon2> reconstruct_2d(const Polygon2& polygon, const ShapeOptions& options,
                                OperationSummary* summary = nullptr);
Result<TriangleMesh> reconstruct_3d(const TriangleMesh& mesh, const ShapeOptions& options,
                                    OperationSummary* summary = nullptr);

// Grows (distance > 0) or shrinks (distance < 0) the balls' shape by |distance|: interior radii
// + distance, exterior radii - distance; balls left with a radius <= 0 are dropped.
template <int D>
Balls<D> offset_balls(const Balls<D>& balls, double distance);

Result<Polygon2> offset_2d(const Polygon2& polygon, double distance, const ShapeOptions& options,
                           OperationSummary* summary = nullptr);
Result<TriangleMesh> offset_3d(const TriangleMesh& mesh, double distance,
                               const ShapeOptions& options, OperationSummary* summary = nullptr);

// a op b (difference: a minus b). An empty result is kInvalidArgument ("the result is empty").
// In 3-D, where the crust of the result's balls is not a valid solid (known to happen along the
// crease of some unions), the result is the exact corefinement of a and b
// (geometry::corefine_boolean) and summary->exact_fallback says so.
Result<Polygon2> boolean_2d(const Polygon2& a, const Polygon2& b, BooleanOp op,
                            const ShapeOptions& options, OperationSummary* summary = nullptr);
Result<TriangleMesh> boolean_3d(const TriangleMesh& a, const TriangleMesh& b, BooleanOp op,
                                const ShapeOptions& options, OperationSummary* summary = nullptr);

// The points where the loops of a and b cross, and (3-D) the segments where their triangles
// cross, for the sampling pools of a boolean.
ExtraFeatures<2> intersection_features_2d(const Polygon2& a, const Polygon2& b);
ExtraFeatures<3> intersection_features_3d(const TriangleMesh& a, const TriangleMesh& b);

}  // namespace hc::abstraction
