// Scale-aware abstraction (thesis Sec. 7.4.2) and engraving (Sec. 7.5): narrow, deep intrusions
// are closed by re-labelling the exterior medial balls inside them as interior; wide ones and
// shallow ones are kept. "Narrow" means narrower than the feature size F: the intrusion holds no
// ball of radius rho = (1 - width_tolerance) F / 2. The closed region ends where a ball of radius
// rho rolling over the intrusion touches its rim (exterior balls whose centre lies in the union of
// the wide exterior balls stay exterior), so the lid is the rolling ball's lower boundary.
//
// 2-D, as the thesis did: on the exterior medial-axis graph (Voronoi vertices joined by Voronoi
// edges), the bridges (Tarjan 1974) form trees hanging from the cycles; every leaf's branch is
// followed towards its cycle while the balls are narrow. Where the radius changes slowly along it
// (|dr/ds| < slow_rate: walls within about 11 degrees of parallel) the intrusion runs deep; its
// depth is the length of those slow stretches plus the radius where they start (the ball there
// reaches the bottom), its width twice their mean radius. Depth / width > depth_ratio (tau) closes
// the subtree the branch leaves the narrow region from.
//
// 3-D, which the thesis left open (our rule): the narrow exterior balls that no wide exterior ball
// covers form pockets, the connected pieces (through the regular triangulation's edges) of the
// region a rolling ball of radius rho cannot reach. That region is exactly what a morphological
// closing would fill; the rule keeps the depth awareness the closing lacks by measuring each
// pocket on the medial structure itself: its width is twice its largest ball radius (for a hole,
// whose medial axis is a curve, the diameter; for a slot or groove, whose medial axis is a sheet,
// the thickness), its depth the mean depth volume / lid area, with the volume the sum of the
// pocket balls' power cells and the lid the power faces between pocket balls and the exterior
// balls left outside. A pocket closes when depth / width > tau. At a concave edge of any opening
// angle above ~30 degrees the pocket is a thin cusp with mean depth well below its width
// (90 degrees: 0.23), so concave edges and corners stay sharp, and shallow holes keep their
// floor. The pocket's medial part is reported as a curve or a sheet (the second and third
// principal extents of its ball centres).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "fabrication/abstraction/operations.h"

namespace hc::abstraction {

struct AbstractionOptions {
  double feature_size = 0.0;      // F, in the input's unit (> 0)
  double depth_ratio = 0.5;       // tau: intrusions deeper than tau times their width close
  double width_tolerance = 0.05;  // gaps within this fraction below F count as F wide
  double slow_rate = 0.2;         // 2-D: |dr/ds| below this is a slowly changing radius
  // 3-D: pockets smaller than this (in r_min; volume^(1/3)) are sampling noise and stay open.
  double min_pocket_size = 2.0;
  ShapeOptions shape;
  Status validate() const;
};

struct Intrusion {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // of its balls (z = 0 in 2-D)
  double width = 0.0;
  double depth = 0.0;
  double ratio = 0.0;  // depth / width
  bool closed = false;
  std::string medial_part;  // 2-D "branch"; 3-D "curve" or "sheet"
  std::size_t balls = 0;
};

template <class Shape, int D>
struct AbstractionResult {
  Shape shape;
  std::vector<Intrusion> intrusions;
  Balls<D> closed;  // the exterior balls re-labelled interior (the closed regions)
  OperationSummary summary;
};

// The abstraction of a polygon / closed mesh. Intrusions lists the closed ones and the narrow
// ones that were kept.
Result<AbstractionResult<Polygon2, 2>> abstract_2d(const Polygon2& polygon,
                                                   const AbstractionOptions& options);
Result<AbstractionResult<TriangleMesh, 3>> abstract_3d(const TriangleMesh& mesh,
                                                       const AbstractionOptions& options);

// The labelling step alone, on balls already built (abstract_* = balls, this, crust). Returns
// the intrusions; flips the closed balls' labels in place.
Result<std::vector<Intrusion>> abstract_balls_2d(const AbstractionOptions& options, Balls2* balls);
Result<std::vector<Intrusion>> abstract_balls_3d(const AbstractionOptions& options, Balls3* balls,
                                                 double r_min);

struct EngraveOptions {
  AbstractionOptions abstraction;
  double depth = 0.0;   // engraving depth d (> 0), the printer's calibrated minimum
  bool emboss = false;  // raise the closed regions by d instead of sinking them
  Status validate() const;
};

// Engraving: the abstraction offset inwards by d, united with the input, so that the closed
// intrusions show as depressions of depth d. Embossing: the abstraction united with the closed
// regions grown by d, so they stand out by d.
Result<AbstractionResult<Polygon2, 2>> engrave_2d(const Polygon2& polygon,
                                                  const EngraveOptions& options);
Result<AbstractionResult<TriangleMesh, 3>> engrave_3d(const TriangleMesh& mesh,
                                                      const EngraveOptions& options);

}  // namespace hc::abstraction
