// Unions of medial balls (thesis Sec. 7.4.1; Amenta et al. 2001, the power crust): the Voronoi
// balls of a dense sampling, labelled interior or exterior, represent a shape and its (bounded)
// embedding at once. In 2-D every Voronoi vertex is kept; in 3-D the thesis's heuristic: the poles
// (per sample the farthest Voronoi vertex, and the farthest on the other side), plus every Voronoi
// ball whose radius exceeds a small threshold.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "common/status.h"
#include "fabrication/abstraction/sampling.h"
#include "geometry/regular_triangulation.h"

namespace hc::abstraction {

template <int D>
struct Balls {
  using Vec = Eigen::Matrix<double, D, 1>;
  std::vector<Vec> centres;
  std::vector<double> radii;
  std::vector<std::uint8_t> interior;  // 1: inside the shape, 0: outside
  // 2-D only (medial_balls_2d): the balls whose Voronoi vertices share a Voronoi edge with ball
  // i's (the Delaunay triangles across its edges), -1 where there is none. The medial-axis graph.
  std::vector<std::array<int, 3>> neighbours;
  // 3-D only (medial_balls_3d): the samples whose Delaunay cell made ball i (indices into
  // `samples`, -1 for a bounding point). Ball i's sphere passes through them, so every power
  // vertex whose four balls share a sample is that sample exactly; the crust snaps to it.
  // Cleared when radii change (offsets), which breaks that degeneracy.
  std::vector<std::array<int, 4>> defining;
  std::vector<Vec> samples;
  std::size_t size() const { return centres.size(); }
  void push_back(const Vec& c, double r, bool in) {
    centres.push_back(c);
    radii.push_back(r);
    interior.push_back(in ? 1 : 0);
  }
};
using Balls2 = Balls<2>;
using Balls3 = Balls<3>;

// Whether a point is inside the shape (the labels of the balls). medial_balls_3d calls it from
// several threads at once.
template <int D>
using InsideTest = std::function<bool(const Eigen::Matrix<double, D, 1>&)>;

// Poles of the first `num_samples` vertices of a Delaunay triangulation (Amenta et al.): plus[i]
// the finite cell whose circumcentre is farthest from sample i, minus[i] the farthest among the
// cells whose circumcentre lies on the other side ((c - s) . (p+ - s) < 0); -1 when none.
struct Poles {
  std::vector<int> plus;
  std::vector<int> minus;
};
Poles compute_poles(const geometry::Triangulation3& dt, std::span<const Eigen::Vector3d> points,
                    std::size_t num_samples);

// Points outside the box `lo`..`hi` grown by `margin` times its diagonal on every side: the four
// (2-D) or eight (3-D) corners, so that every sample's Voronoi cell is bounded.
template <int D>
std::vector<Eigen::Matrix<double, D, 1>> bounding_points(const Eigen::Matrix<double, D, 1>& lo,
                                                         const Eigen::Matrix<double, D, 1>& hi,
                                                         double margin);

struct MedialOptions {
  // 3-D: Voronoi balls that are not poles are kept when their radius exceeds this (in the input's
  // unit; 0: keep_radius_factor * the samples' smallest r). Thesis: "a (small) threshold".
  double keep_radius = 0.0;
  double keep_radius_factor = 2.0;
  double bound_margin = 1.0;  // bounding points, in bounding-box diagonals beyond the samples

  Status validate() const;
};

struct MedialSummary {
  std::size_t voronoi_vertices = 0;
  std::size_t poles = 0;  // 3-D
  std::size_t balls = 0;
  std::size_t interior = 0;
  double time_s = 0.0;
};

// The medial balls of `samples` (at least 3 / 4 points not collinear / coplanar), labelled by
// `inside` at their centres.
Result<Balls2> medial_balls_2d(const Samples2& samples, const InsideTest<2>& inside,
                               const MedialOptions& options = {}, MedialSummary* summary = nullptr);
Result<Balls3> medial_balls_3d(const Samples3& samples, const InsideTest<3>& inside,
                               const MedialOptions& options = {}, MedialSummary* summary = nullptr);

}  // namespace hc::abstraction
