// Planar shapes for the 2-D side of scale-aware fabrication (the thesis's figures are 2-D): a set
// of closed polygonal loops whose interior is given by the even-odd rule, so outer boundaries and
// holes may come in either orientation (SVG's fill-rule="evenodd").
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "common/status.h"

namespace hc::abstraction {

using Loop2 = std::vector<Eigen::Vector2d>;  // closed: the last point connects to the first

struct Polygon2 {
  std::vector<Loop2> loops;

  std::size_t num_points() const;
  Eigen::AlignedBox2d bounding_box() const;
};

// Signed area of a loop (positive counter-clockwise).
double signed_area(const Loop2& loop);
// Area enclosed by the even-odd rule: the sum of |area| of the loops, alternating signs by
// nesting depth (loops must not cross each other).
double area(const Polygon2& polygon);
// Whether p lies inside by the even-odd rule (crossing number over all loops).
bool inside(const Polygon2& polygon, const Eigen::Vector2d& p);
// Each loop has at least 3 points, finite coordinates, no two consecutive points equal and a
// non-zero area; kInvalidArgument naming the loop otherwise. `what` prefixes the message.
Status validate(const Polygon2& polygon, std::string_view what);
// Loops turned counter-clockwise where their nesting depth is even and clockwise where it is odd,
// so that the interior is on the left of every edge.
void orient(Polygon2* polygon);

}  // namespace hc::abstraction
