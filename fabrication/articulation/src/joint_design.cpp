#include "fabrication/articulation/joint_design.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <vector>

namespace hc::articulation {
namespace {

constexpr double kInfeasible = -std::numeric_limits<double>::infinity();

// Max-min search over the unit box [0, 1]^N: a grid, then repeated zooms around the best point.
// Written here rather than taken from a library because the objective (a minimum of areas, one of
// them stepping where a range cone reaches the equator) is neither smooth nor convex, which
// gradient and simplex methods handle badly, and N <= 3 makes a zooming grid cheap and exact to
// the grid's last spacing.
template <int N>
std::array<double, N> zoom_search(const std::function<double(const std::array<double, N>&)>& f,
                                  int grid, int levels, double* best_value, int* evaluations) {
  std::array<double, N> lo, hi, best{};
  lo.fill(0.0);
  hi.fill(1.0);
  *best_value = kInfeasible;
  for (int level = 0; level < levels; ++level) {
    std::array<double, N> level_best = best;
    double level_value = kInfeasible;
    std::array<int, N> idx{};
    while (true) {
      std::array<double, N> x;
      for (int k = 0; k < N; ++k) x[k] = lo[k] + (hi[k] - lo[k]) * (idx[k] + 0.5) / grid;
      const double v = f(x);
      ++*evaluations;
      if (v > level_value) level_value = v, level_best = x;
      int k = 0;
      while (k < N && ++idx[k] == grid) idx[k++] = 0;
      if (k == N) break;
    }
    if (level_value > *best_value) *best_value = level_value, best = level_best;
    if (*best_value == kInfeasible) break;
    for (int k = 0; k < N; ++k) {
      const double w = 2.0 * (hi[k] - lo[k]) / grid;
      lo[k] = std::max(0.0, best[k] - w);
      hi[k] = std::min(1.0, best[k] + w);
    }
  }
  return best;
}

double clearance_angle(double d, double radius) { return std::asin(std::min(1.0, d / radius)); }

// Area of the part of a disc of radius rho beyond a chord at distance y0 from its centre.
double disc_segment(double rho, double y0) {
  if (y0 >= rho) return 0.0;
  if (y0 <= -rho) return std::numbers::pi * rho * rho;
  return rho * rho * std::acos(y0 / rho) - y0 * std::sqrt(rho * rho - y0 * y0);
}

// The smallest feasible socket radius: r' = r - d > s0 = sqrt(r^2 - r'^2) needs r > (2 + sqrt 2) d.
double min_socket_radius(double d) { return (2.0 + std::numbers::sqrt2) * d; }

}  // namespace

double BallRange::at(double theta) const {
  const double c = std::cos(theta), s = std::sin(theta);
  const double den = std::sqrt(phi_a * phi_a * c * c + phi_f * phi_f * s * s);
  return den > 0 ? phi_f * phi_a / den : 0.0;
}

Status JointDesignOptions::validate() const {
  if (!(clearance_m > 0) || !std::isfinite(clearance_m))
    return invalid_argument(fmt::format("clearance must be > 0 m, got {}", clearance_m));
  if (theta_samples < 8 || grid < 8 || levels < 1)
    return invalid_argument("joint design: theta_samples and grid must be >= 8, levels >= 1");
  return {};
}

std::array<double, 3> ball_socket_areas(double r_max, double r, double h, const BallRange& range,
                                        const JointDesignOptions& options) {
  const double d = options.clearance_m;
  const double rb = r - d;
  const double s0 = std::sqrt(std::max(0.0, r * r - rb * rb));
  const double alpha = std::acos(std::clamp(h / rb, -1.0, 1.0));
  const double delta = clearance_angle(d, rb);
  const int n = options.theta_samples;
  const double dtheta = 2 * std::numbers::pi / n;
  double a1 = 0.0, lip = 0.0;
  for (int i = 0; i < n; ++i) {
    const double psi = alpha + range.at((i + 0.5) * dtheta) + delta;
    if (psi < std::numbers::pi / 2) {
      a1 += 0.5 * (r_max * r_max - r * r) * dtheta;
      // Eq. 6.6: the cone of half-angle psi meets the lip's cylinder at height r' / tan(psi).
      lip += std::clamp(rb / std::tan(psi) - s0, 0.0, h - s0) * dtheta;
    }
  }
  return {a1, rb * lip, std::numbers::pi * (rb * rb - h * h)};
}

std::array<double, 3> hinge_areas(double r_max, double R, double r, double b,
                                  const HingeRange& range, const JointDesignOptions& options) {
  const double d = options.clearance_m;
  const double knuckle = R - d;
  const double alpha = std::asin(std::clamp((knuckle - r) / knuckle, 0.0, 1.0));
  const double delta = clearance_angle(d, knuckle);
  double a3 = std::numbers::pi * r_max * r_max - 2 * b * (R - r + d);
  // A swing wedge reaching the axis plane removes the fork's disc beyond R - d on that side (the
  // strip of the slot there, b x d, was already counted).
  for (double swing : {range.forward, range.backward})
    if (alpha + swing + delta >= std::numbers::pi / 2) a3 -= disc_segment(r_max, knuckle) - b * d;
  return {2 * std::numbers::pi * (r - d) * (r - d), 2 * (b - 2 * d) * (knuckle - r), a3};
}

BallSocketDesign design_ball_socket(double r_max, const BallRange& range,
                                    const JointDesignOptions& options) {
  BallSocketDesign out;
  const double d = options.clearance_m;
  out.clearance = d;
  const double r_lo = min_socket_radius(d);
  if (!(r_max > r_lo)) return out;
  // Unit box -> (r, h): r in (r_lo, r_max), h in (s0(r), r - d).
  const auto map = [&](const std::array<double, 2>& x, double* r, double* h) {
    *r = r_lo + x[0] * (r_max - r_lo);
    const double rb = *r - d;
    const double s0 = std::sqrt(*r * *r - rb * rb);
    *h = s0 + x[1] * (rb - s0);
  };
  const auto objective = [&](const std::array<double, 2>& x) {
    double r, h;
    map(x, &r, &h);
    const std::array<double, 3> a = ball_socket_areas(r_max, r, h, range, options);
    return std::min({a[0], a[1], a[2]});
  };
  double best = 0.0;
  const std::array<double, 2> x =
      zoom_search<2>(objective, options.grid, options.levels, &best, &out.evaluations);
  if (best == kInfeasible) return out;
  map(x, &out.r, &out.h);
  out.feasible = true;
  out.ball_radius = out.r - d;
  out.s0 = std::sqrt(out.r * out.r - out.ball_radius * out.ball_radius);
  out.alpha = std::acos(out.h / out.ball_radius);
  out.delta = clearance_angle(d, out.ball_radius);
  out.areas = ball_socket_areas(r_max, out.r, out.h, range, options);
  out.min_area = std::min({out.areas[0], out.areas[1], out.areas[2]});
  for (int i = 0; i < options.theta_samples; ++i) {
    const double psi =
        out.alpha + range.at((i + 0.5) * 2 * std::numbers::pi / options.theta_samples) + out.delta;
    const double top = psi < std::numbers::pi / 2
                           ? std::clamp(out.ball_radius / std::tan(psi), out.s0, out.h)
                           : out.s0;
    out.opening_radius =
        std::max(out.opening_radius, std::sqrt(std::max(0.0, out.r * out.r - top * top)));
  }
  return out;
}

HingeDesign design_hinge(double r_max, const HingeRange& range, const JointDesignOptions& options) {
  HingeDesign out;
  const double d = options.clearance_m;
  out.clearance = d;
  // r > d, R > r + d, b > 2d and (b/2)^2 + R^2 < r_max^2 need r_max > sqrt(d^2 + (2d)^2) at least.
  if (!(r_max > std::sqrt(5.0) * d)) return out;
  const auto map = [&](const std::array<double, 3>& x, double* r, double* R, double* b) {
    *r = d + x[0] * (r_max - d);
    *R = *r + d + x[1] * (r_max - *r - d);
    const double b_max = 2 * std::sqrt(std::max(0.0, r_max * r_max - *R * *R));
    *b = 2 * d + x[2] * (b_max - 2 * d);
    return b_max > 2 * d && *R < r_max;
  };
  const auto objective = [&](const std::array<double, 3>& x) {
    double r, R, b;
    if (!map(x, &r, &R, &b)) return kInfeasible;
    const std::array<double, 3> a = hinge_areas(r_max, R, r, b, range, options);
    return std::min({a[0], a[1], a[2]});
  };
  double best = 0.0;
  const std::array<double, 3> x =
      zoom_search<3>(objective, options.grid, options.levels, &best, &out.evaluations);
  if (best == kInfeasible) return out;
  map(x, &out.r, &out.R, &out.b);
  out.feasible = true;
  out.alpha = std::asin((out.R - d - out.r) / (out.R - d));
  out.delta = clearance_angle(d, out.R - d);
  out.areas = hinge_areas(r_max, out.R, out.r, out.b, range, options);
  out.min_area = std::min({out.areas[0], out.areas[1], out.areas[2]});
  return out;
}

}  // namespace hc::articulation
