// Delaunay and regular triangulations of points in the plane, and their duals, the Voronoi and
// power diagrams (thesis Appendix B), by CGAL's Regular_triangulation_2. The power vertex of every
// triangle (its orthocentre: equal power to the three weighted corners; the circumcentre when all
// weights are zero) is constructed with exact arithmetic and rounded once to double. The 2-D
// medial-ball code of fabrication/abstraction walks this output; no CGAL type appears here.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/status.h"

namespace hc::geometry {

struct Triangulation2 {
  // Every triangle, finite or not: corners as indices into the input points, counter-clockwise,
  // -1 standing for the infinite vertex.
  std::vector<std::array<int, 3>> triangles;
  // neighbours[t][k]: the triangle across the edge opposite corner k of triangle t.
  std::vector<std::array<int, 3>> neighbours;
  // Power vertex (circumcentre without weights) of each finite triangle and the squared radius of
  // its orthogonal circle (circumradius squared without weights); NaN for infinite triangles.
  std::vector<Eigen::Vector2d> centres;
  std::vector<double> squared_radii;
  // Per input point: 1 when it is a vertex; 0 for a duplicate or a hidden (empty power cell) ball.
  std::vector<std::uint8_t> is_vertex;
  bool is_finite(int t) const {
    const auto& c = triangles[static_cast<std::size_t>(t)];
    return c[0] >= 0 && c[1] >= 0 && c[2] >= 0;
  }
};

// Triangulates `points` (finite; at least 3 not collinear). `weights` empty: Delaunay; otherwise
// weights[i] is the squared radius of ball i and the result is the regular triangulation.
// kInvalidArgument for non-finite input, mismatched sizes or collinear points; kInternal when CGAL
// fails.
Result<Triangulation2> triangulate_2d(std::span<const Eigen::Vector2d> points,
                                      std::span<const double> weights = {});

// For each query, the smallest power distance |q - c_i|^2 - w_i over the weighted points and the
// index of that ball (negative power: q is inside the union of the balls).
struct PowerQuery2 {
  std::vector<double> power;
  std::vector<int> ball;
};
Result<PowerQuery2> nearest_power_2d(std::span<const Eigen::Vector2d> centres,
                                     std::span<const double> weights,
                                     std::span<const Eigen::Vector2d> queries);

}  // namespace hc::geometry
