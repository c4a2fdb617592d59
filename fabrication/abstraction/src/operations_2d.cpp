// Offsets and booleans in the plane (operations.h), and what 2-D and 3-D share.
#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "common/clock.h"
#include "fabrication/abstraction/operations.h"
#include "operations_internal.h"

namespace hc::abstraction {
namespace {

// Where segments pq and rs cross (proper crossings and touching points), if they do.
std::optional<Eigen::Vector2d> crossing(const Eigen::Vector2d& p, const Eigen::Vector2d& q,
                                        const Eigen::Vector2d& r, const Eigen::Vector2d& s) {
  const Eigen::Vector2d d1 = q - p, d2 = s - r;
  const double den = d1.x() * d2.y() - d1.y() * d2.x();
  if (den == 0.0) return std::nullopt;  // parallel or collinear: no single crossing point
  const Eigen::Vector2d w = r - p;
  const double t = (w.x() * d2.y() - w.y() * d2.x()) / den;
  const double u = (w.x() * d1.y() - w.y() * d1.x()) / den;
  if (t < 0 || t > 1 || u < 0 || u > 1) return std::nullopt;
  return p + t * d1;
}

}  // namespace

Status ShapeOptions::validate() const {
  HC_RETURN_IF_ERROR(sampling.validate());
  return medial.validate();
}

const char* to_string(BooleanOp op) {
  switch (op) {
    case BooleanOp::kUnion:
      return "union";
    case BooleanOp::kDifference:
      return "difference";
    case BooleanOp::kIntersection:
      return "intersection";
  }
  return "?";
}

Result<BooleanOp> parse_boolean_op(std::string_view name) {
  if (name == "union") return BooleanOp::kUnion;
  if (name == "difference") return BooleanOp::kDifference;
  if (name == "intersection") return BooleanOp::kIntersection;
  return invalid_argument(fmt::format(
      "unknown boolean operation \"{}\"; expected union, difference or intersection", name));
}

template <int D>
Balls<D> offset_balls(const Balls<D>& balls, double distance) {
  Balls<D> out;
  for (std::size_t i = 0; i < balls.size(); ++i) {
    const double r = balls.radii[i] + (balls.interior[i] ? distance : -distance);
    if (r > 0) out.push_back(balls.centres[i], r, balls.interior[i] != 0);
  }
  return out;  // no `defining`: the radii changed, the samples are no longer on the spheres
}
template Balls2 offset_balls<2>(const Balls2&, double);
template Balls3 offset_balls<3>(const Balls3&, double);

Result<Balls2> polygon_balls(const Polygon2& polygon, const ShapeOptions& options,
                             OperationSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(Samples2 samples,
                      sample_polygon(polygon, options.sampling, {}, &summary->sampling));
  summary->samples = samples.size();
  HC_ASSIGN_OR_RETURN(Balls2 balls,
                      medial_balls_2d(
                          samples, [&](const Eigen::Vector2d& p) { return inside(polygon, p); },
                          options.medial, &summary->medial));
  summary->balls = balls.size();
  return balls;
}

Result<Polygon2> reconstruct_2d(const Polygon2& polygon, const ShapeOptions& options,
                                OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  OperationSummary sum;
  HC_ASSIGN_OR_RETURN(Balls2 balls, polygon_balls(polygon, options, &sum));
  HC_ASSIGN_OR_RETURN(Polygon2 out, power_crust_2d(balls, &sum.crust));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

Result<Polygon2> offset_2d(const Polygon2& polygon, double distance, const ShapeOptions& options,
                           OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!std::isfinite(distance)) return invalid_argument("offset: the distance is not finite");
  OperationSummary sum;
  HC_ASSIGN_OR_RETURN(Balls2 balls, polygon_balls(polygon, options, &sum));
  const Balls2 moved = offset_balls(balls, distance);
  std::size_t in = 0;
  for (const auto l : moved.interior) in += l;
  if (in == 0)
    return invalid_argument(fmt::format("offset: shrinking by {} leaves nothing", -distance));
  HC_ASSIGN_OR_RETURN(Polygon2 out, power_crust_2d(moved, &sum.crust));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

ExtraFeatures<2> intersection_features_2d(const Polygon2& a, const Polygon2& b) {
  // All pairs with a bounding-box test: 2-D outlines have thousands of points at most.
  ExtraFeatures<2> f;
  for (const auto& la : a.loops) {
    for (std::size_t i = 0; i < la.size(); ++i) {
      const auto& p = la[i];
      const auto& q = la[(i + 1) % la.size()];
      const Eigen::AlignedBox2d ba(p.cwiseMin(q), p.cwiseMax(q));
      for (const auto& lb : b.loops) {
        for (std::size_t j = 0; j < lb.size(); ++j) {
          const auto& r = lb[j];
          const auto& s = lb[(j + 1) % lb.size()];
          if (!ba.intersects(Eigen::AlignedBox2d(r.cwiseMin(s), r.cwiseMax(s)))) continue;
          if (const auto x = crossing(p, q, r, s)) f.corners.push_back(*x);
        }
      }
    }
  }
  return f;
}

Result<Polygon2> boolean_2d(const Polygon2& a, const Polygon2& b, BooleanOp op,
                            const ShapeOptions& options, OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(validate(a, "boolean: first input"));
  HC_RETURN_IF_ERROR(validate(b, "boolean: second input"));
  OperationSummary sum;
  const ExtraFeatures<2> features = intersection_features_2d(a, b);
  sum.intersection_points = features.corners.size();
  // One sampling scale for both: the fractions refer to the bounding box of both inputs.
  ShapeOptions o = options;
  const Eigen::AlignedBox2d box = a.bounding_box().merged(b.bounding_box());
  const double diag = box.diagonal().norm();
  if (o.sampling.r_min <= 0) o.sampling.r_min = o.sampling.r_min_fraction * diag;
  if (o.sampling.r_uniform <= 0) o.sampling.r_uniform = o.sampling.r_uniform_fraction * diag;
  HC_ASSIGN_OR_RETURN(Samples2 sa, sample_polygon(a, o.sampling, features, &sum.sampling));
  HC_ASSIGN_OR_RETURN(Samples2 sb, sample_polygon(b, o.sampling, features));
  Samples2 all;
  for (int which = 0; which < 2; ++which) {
    const Samples2& s = which == 0 ? sa : sb;
    const Polygon2& other = which == 0 ? b : a;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (internal::is_feature(s.kinds[i])
              ? which == 0
              : internal::keep_sample(op, which == 0, inside(other, s.points[i]))) {
        all.points.push_back(s.points[i]);
        all.radii.push_back(s.radii[i]);
        all.kinds.push_back(s.kinds[i]);
      }
    }
  }
  sum.samples = all.size();
  if (all.size() < 3)
    return invalid_argument(fmt::format("boolean {}: the result is empty", to_string(op)));
  HC_ASSIGN_OR_RETURN(Balls2 balls, medial_balls_2d(
                                        all,
                                        [&](const Eigen::Vector2d& p) {
                                          return internal::in_result(op, inside(a, p),
                                                                     inside(b, p));
                                        },
                                        o.medial, &sum.medial));
  sum.balls = balls.size();
  std::size_t in = 0;
  for (const auto l : balls.interior) in += l;
  if (in == 0)
    return invalid_argument(fmt::format("boolean {}: the result is empty", to_string(op)));
  HC_ASSIGN_OR_RETURN(Polygon2 out, power_crust_2d(balls, &sum.crust));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

}  // namespace hc::abstraction
