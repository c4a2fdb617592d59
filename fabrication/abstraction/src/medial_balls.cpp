#include "fabrication/abstraction/medial_balls.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "common/clock.h"
#include "geometry/triangulation_2d.h"

namespace hc::abstraction {

Status MedialOptions::validate() const {
  if (!(keep_radius >= 0) || !(keep_radius_factor >= 0)) {
    return invalid_argument("medial balls: keep_radius and keep_radius_factor must be >= 0");
  }
  if (!(bound_margin > 0)) return invalid_argument("medial balls: bound_margin must be > 0");
  return {};
}

template <int D>
std::vector<Eigen::Matrix<double, D, 1>> bounding_points(const Eigen::Matrix<double, D, 1>& lo,
                                                         const Eigen::Matrix<double, D, 1>& hi,
                                                         double margin) {
  const double grow = margin * (hi - lo).norm();
  const Eigen::Matrix<double, D, 1> a = lo.array() - grow;
  const Eigen::Matrix<double, D, 1> b = hi.array() + grow;
  std::vector<Eigen::Matrix<double, D, 1>> out;
  for (int corner = 0; corner < (1 << D); ++corner) {
    Eigen::Matrix<double, D, 1> p;
    for (int k = 0; k < D; ++k) p[k] = (corner >> k) & 1 ? b[k] : a[k];
    out.push_back(p);
  }
  return out;
}
template std::vector<Eigen::Vector2d> bounding_points<2>(const Eigen::Vector2d&,
                                                         const Eigen::Vector2d&, double);
template std::vector<Eigen::Vector3d> bounding_points<3>(const Eigen::Vector3d&,
                                                         const Eigen::Vector3d&, double);

Poles compute_poles(const geometry::Triangulation3& dt, std::span<const Eigen::Vector3d> points,
                    std::size_t num_samples) {
  Poles poles;
  poles.plus.assign(num_samples, -1);
  poles.minus.assign(num_samples, -1);
  std::vector<double> best(num_samples, -1.0);
  const auto n = static_cast<int>(num_samples);
  for (std::size_t c = 0; c < dt.cells.size(); ++c) {
    if (!dt.is_finite(static_cast<int>(c))) continue;
    for (const int v : dt.cells[c]) {
      if (v >= n) continue;
      const double d = (dt.centres[c] - points[static_cast<std::size_t>(v)]).squaredNorm();
      if (d > best[static_cast<std::size_t>(v)]) {
        best[static_cast<std::size_t>(v)] = d;
        poles.plus[static_cast<std::size_t>(v)] = static_cast<int>(c);
      }
    }
  }
  std::fill(best.begin(), best.end(), -1.0);
  for (std::size_t c = 0; c < dt.cells.size(); ++c) {
    if (!dt.is_finite(static_cast<int>(c))) continue;
    for (const int v : dt.cells[c]) {
      if (v >= n) continue;
      const auto i = static_cast<std::size_t>(v);
      if (poles.plus[i] < 0) continue;
      const Eigen::Vector3d to_plus =
          dt.centres[static_cast<std::size_t>(poles.plus[i])] - points[i];
      const Eigen::Vector3d to_c = dt.centres[c] - points[i];
      if (to_c.dot(to_plus) >= 0) continue;
      if (to_c.squaredNorm() > best[i]) {
        best[i] = to_c.squaredNorm();
        poles.minus[i] = static_cast<int>(c);
      }
    }
  }
  return poles;
}

namespace {

template <int D>
Eigen::AlignedBox<double, D> box_of(const std::vector<Eigen::Matrix<double, D, 1>>& pts) {
  Eigen::AlignedBox<double, D> box;
  for (const auto& p : pts) box.extend(p);
  return box;
}

}  // namespace

Result<Balls2> medial_balls_2d(const Samples2& samples, const InsideTest<2>& inside,
                               const MedialOptions& options, MedialSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  if (samples.size() < 3) return invalid_argument("medial balls: fewer than 3 samples");
  std::vector<Eigen::Vector2d> pts = samples.points;
  const auto box = box_of<2>(pts);
  for (const auto& b : bounding_points<2>(box.min(), box.max(), options.bound_margin))
    pts.push_back(b);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation2 dt, geometry::triangulate_2d(pts));
  Balls2 balls;
  MedialSummary sum;
  std::vector<int> ball_of(dt.triangles.size(), -1);
  for (std::size_t t = 0; t < dt.triangles.size(); ++t) {
    if (!dt.is_finite(static_cast<int>(t))) continue;
    ++sum.voronoi_vertices;
    ball_of[t] = static_cast<int>(balls.size());
    balls.push_back(dt.centres[t], std::sqrt(dt.squared_radii[t]), inside(dt.centres[t]));
    sum.interior += balls.interior.back();
  }
  balls.neighbours.resize(balls.size());
  for (std::size_t t = 0; t < dt.triangles.size(); ++t) {
    if (ball_of[t] < 0) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      balls.neighbours[static_cast<std::size_t>(ball_of[t])][k] =
          ball_of[static_cast<std::size_t>(dt.neighbours[t][k])];
    }
  }
  sum.balls = balls.size();
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return balls;
}

Result<Balls3> medial_balls_3d(const Samples3& samples, const InsideTest<3>& inside,
                               const MedialOptions& options, MedialSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  if (samples.size() < 4) return invalid_argument("medial balls: fewer than 4 samples");
  std::vector<Eigen::Vector3d> pts = samples.points;
  const std::size_t n = pts.size();
  const auto box = box_of<3>(pts);
  for (const auto& b : bounding_points<3>(box.min(), box.max(), options.bound_margin))
    pts.push_back(b);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation3 dt, geometry::triangulate_3d(pts));
  const Poles poles = compute_poles(dt, pts, n);
  double keep = options.keep_radius;
  if (keep <= 0) {
    double r_min = std::numeric_limits<double>::infinity();
    for (const double r : samples.radii) r_min = std::min(r_min, r);
    keep = options.keep_radius_factor * r_min;
  }
  std::vector<std::uint8_t> take(dt.cells.size(), 0);
  MedialSummary sum;
  for (std::size_t i = 0; i < n; ++i) {
    for (const int c : {poles.plus[i], poles.minus[i]}) {
      if (c >= 0 && !take[static_cast<std::size_t>(c)]) {
        take[static_cast<std::size_t>(c)] = 1;
        ++sum.poles;
      }
    }
  }
  const double keep2 = keep * keep;
  std::vector<std::size_t> kept;
  for (std::size_t c = 0; c < dt.cells.size(); ++c) {
    if (!dt.is_finite(static_cast<int>(c))) continue;
    ++sum.voronoi_vertices;
    if (take[c] || dt.squared_radii[c] > keep2) kept.push_back(c);
  }
  // The labels in parallel (InsideTest may be called from several threads).
  std::vector<std::uint8_t> in(kept.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, kept.size()), [&](const auto& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k)
      in[k] = inside(dt.centres[kept[k]]) ? 1 : 0;
  });
  Balls3 balls;
  // Sized once: growing by doubling would touch twice the memory (see regular_triangulation_3.cpp
  // on what fresh pages cost).
  balls.centres.reserve(kept.size());
  balls.radii.reserve(kept.size());
  balls.interior.reserve(kept.size());
  balls.defining.reserve(kept.size());
  for (std::size_t k = 0; k < kept.size(); ++k) {
    const std::size_t c = kept[k];
    balls.push_back(dt.centres[c], std::sqrt(dt.squared_radii[c]), in[k] != 0);
    std::array<int, 4> def{};
    for (std::size_t j = 0; j < 4; ++j)
      def[j] = dt.cells[c][j] < static_cast<int>(n) ? dt.cells[c][j] : -1;
    balls.defining.push_back(def);
    sum.interior += balls.interior.back();
  }
  balls.samples = samples.points;
  sum.balls = balls.size();
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return balls;
}

}  // namespace hc::abstraction
