// Delaunay and regular (weighted Delaunay) triangulations of points in space, and their duals, the
// Voronoi and power diagrams (thesis Appendix B), by CGAL's Regular_triangulation_3 with exact
// predicates. The power vertex of every cell (the orthocentre: the point of equal power to its
// four weighted corners) is constructed in double, so cells that share a power vertex exactly may
// get positions a few ulps apart (see regular_triangulation_3.cpp for why not exactly). Inputs of
// 20,000 points or more are inserted in parallel (TBB) while the machine has an idle core; their
// cells are then sorted into a canonical order, so the output is the same on every run, parallel
// or not. The medial-ball code of fabrication/abstraction walks this output; no CGAL type appears
// here.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/status.h"

namespace hc::geometry {

struct Triangulation3 {
  // Every cell, finite or not: its four corners as indices into the input points, -1 standing for
  // the infinite vertex. Corners are positively oriented (CGAL's convention) for finite cells.
  std::vector<std::array<int, 4>> cells;
  // neighbours[c][k]: the cell sharing the facet opposite corner k of cell c.
  std::vector<std::array<int, 4>> neighbours;
  // The power vertex (weights given) or circumcentre (no weights) of each finite cell, and its
  // power radius squared (the squared radius of the orthogonal sphere; for Delaunay the squared
  // circumradius). NaN for infinite cells.
  std::vector<Eigen::Vector3d> centres;
  std::vector<double> squared_radii;
  // Per input point: 1 when it is a vertex of the triangulation; 0 when it was a duplicate of an
  // earlier point or its ball lies inside the others' union so that its power cell is empty.
  std::vector<std::uint8_t> is_vertex;
  bool is_finite(int cell) const {
    return cells[static_cast<std::size_t>(cell)][0] >= 0 &&
           cells[static_cast<std::size_t>(cell)][1] >= 0 &&
           cells[static_cast<std::size_t>(cell)][2] >= 0 &&
           cells[static_cast<std::size_t>(cell)][3] >= 0;
  }
};

// How inputs of 20,000 points or more are inserted (smaller ones always sequentially): kAuto in
// parallel while no other thread is runnable on the core it would take. The output does not
// depend on it.
enum class Insertion { kAuto, kSequential, kParallel };

struct Triangulate3Options {
  Insertion insertion = Insertion::kAuto;
  // Empty, or a label per point: then centres and squared_radii are computed only for the finite
  // cells whose corners do not all carry the same label (NaN for the others). A power crust needs
  // only the cells between interior and exterior balls (half of them on bench_abstraction's
  // fandisk).
  std::span<const std::uint8_t> centres_between;
};

// Triangulates `points` (finite coordinates; at least 4 not coplanar). With `weights` empty this is
// the Delaunay triangulation; otherwise weights[i] is the squared radius of ball i (any sign) and
// the result is the regular triangulation, dual to the power diagram. kInvalidArgument for
// non-finite input, mismatched sizes or a degenerate (coplanar) point set; kInternal when CGAL
// fails.
Result<Triangulation3> triangulate_3d(std::span<const Eigen::Vector3d> points,
                                      std::span<const double> weights = {},
                                      const Triangulate3Options& options = {});

// The indices of `points` in their order along a Hilbert curve (CGAL::hilbert_sort, median
// policy; deterministic). Points in this order keep neighbours near each other in memory, and so
// does everything built from them in their order: the triangulations above, the balls and crust of
// fabrication/abstraction (on bench_abstraction's 100k samples the crust ran 0.62 -> 0.44 s and the
// power vertices 0.22 -> 0.13 s with the samples in this order).
std::vector<std::size_t> spatial_order(std::span<const Eigen::Vector3d> points);

// For each query point, the smallest power distance |q - c_i|^2 - w_i over the weighted points
// (the ball whose power cell contains q) and that ball's index: q lies inside the union of the
// balls exactly when the power is negative. Same preconditions as triangulate_3d; any number of
// balls >= 1.
struct PowerQuery {
  std::vector<double> power;
  std::vector<int> ball;
};
Result<PowerQuery> nearest_power_3d(std::span<const Eigen::Vector3d> centres,
                                    std::span<const double> weights,
                                    std::span<const Eigen::Vector3d> queries);

}  // namespace hc::geometry
