// The max-min joint designs of thesis Sec. 6.4.2 against optima derived by hand: Fig. 6.4.7's
// single point where the three critical areas are equal.
#include "fabrication/articulation/joint_design.h"
#include "test_units.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>

namespace hc::articulation {
namespace {

using testing::kMm;

// Root of a monotone function on [lo, hi] by bisection (f(lo) and f(hi) of opposite signs).
double bisect(const std::function<double(double)>& f, double lo, double hi) {
  const bool rising = f(hi) > f(lo);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    ((f(mid) > 0) == rising ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(JointDesign, BallAndSocketOptimumHasThreeEqualAreas) {
  // PolyJet clearance d = 0.3 mm (thesis Sec. 6.5), r_max = 5 mm, no range (phi = 0).
  // By hand (Fig. 6.4.6): A1 = pi (R^2 - r^2), A2 = 2 pi r' (h - s0), A3 = pi (r'^2 - h^2) with
  // r' = r - d, s0 = sqrt(r^2 - r'^2). A1 = A3 gives h = sqrt(r'^2 - R^2 + r^2); A2 = A3 is then
  // one equation in r, solved by bisection. With phi = 0 no range cut applies at this point
  // (checked below), so these are the model's own areas.
  const double d = 0.3 * kMm, R = 5 * kMm;
  const auto h_of = [&](double r) {
    const double rb = r - d;
    return std::sqrt(std::max(0.0, rb * rb - R * R + r * r));
  };
  const auto g = [&](double r) {
    const double rb = r - d, h = h_of(r), s0 = std::sqrt(r * r - rb * rb);
    return 2 * rb * (h - s0) - (rb * rb - h * h);
  };
  const double r_star = bisect(g, (2 + std::sqrt(2.0)) * d * 1.01, R * 0.999);
  const double h_star = h_of(r_star);
  const double a_star = std::numbers::pi * (R * R - r_star * r_star);

  JointDesignOptions options;
  options.clearance_m = d;
  const BallSocketDesign design = design_ball_socket(R, BallRange{}, options);
  ASSERT_TRUE(design.feasible);
  EXPECT_NEAR(design.r, r_star, 2e-3 * r_star);
  EXPECT_NEAR(design.h, h_star, 5e-3 * h_star);
  EXPECT_NEAR(design.min_area, a_star, 1e-3 * a_star);
  for (double a : design.areas) EXPECT_NEAR(a, a_star, 5e-3 * a_star);
  // The lip holds: the opening is narrower than the ball.
  EXPECT_LT(design.opening_radius, design.ball_radius);
  // The closed form's A2 (no cut) is what the model computed.
  const double rb = r_star - d, s0 = std::sqrt(r_star * r_star - rb * rb);
  EXPECT_NEAR(ball_socket_areas(R, r_star, h_star, BallRange{}, options)[1],
              2 * std::numbers::pi * rb * (h_star - s0), 1e-6 * a_star);
  // ~12.4 mm^2 for r_max = 5 mm: above the thesis's A_min = 10 mm^2.
  EXPECT_GT(design.min_area, 10 * kMm * kMm);
}

TEST(JointDesign, BallRangeCutsTheLipAsEq66) {
  // Eq. 6.6 at one point: r = 3 mm, h = 2 mm, d = 0.3 mm, a round cone phi = 20 deg. With
  // alpha = acos(h / r') and delta = asin(d / r'), the cone psi = alpha + phi + delta meets the
  // lip cylinder at z = r' / tan(psi) for every theta, so A2 = 2 pi r' clamp(z - s0, 0, h - s0).
  const double d = 0.3 * kMm, r = 3 * kMm, h = 2 * kMm, rb = r - d;
  const double phi = 20 * std::numbers::pi / 180;
  const double psi = std::acos(h / rb) + phi + std::asin(d / rb);
  const double s0 = std::sqrt(r * r - rb * rb);
  const double expected =
      2 * std::numbers::pi * rb * std::clamp(rb / std::tan(psi) - s0, 0.0, h - s0);
  JointDesignOptions options;
  options.clearance_m = d;
  const auto a = ball_socket_areas(5 * kMm, r, h, BallRange{phi, phi}, options);
  EXPECT_NEAR(a[1], expected, 1e-9 * kMm * kMm);
  EXPECT_LT(a[1], 2 * std::numbers::pi * rb * (h - s0));  // the range did cut
  // Past 90 deg the cone reaches the equator and A1 and the lip vanish in every direction.
  const auto wide = ball_socket_areas(
      5 * kMm, r, h, BallRange{std::numbers::pi / 2, std::numbers::pi / 2}, options);
  EXPECT_EQ(wide[0], 0.0);
  EXPECT_EQ(wide[1], 0.0);
  // An elliptical range: phi(0) = phi_f, phi(pi/2) = phi_a.
  const BallRange ellipse{0.3, 0.1};
  EXPECT_NEAR(ellipse.at(0), 0.3, 1e-12);
  EXPECT_NEAR(ellipse.at(std::numbers::pi / 2), 0.1, 1e-12);
  EXPECT_NEAR(ellipse.at(std::numbers::pi), 0.3, 1e-12);
}

TEST(JointDesign, HingeOptimumBalancesPinAndKnuckleOnTheSphereConstraint) {
  // d = 0.3 mm, r_max = 5 mm, no swing range. Without the sphere constraint the max-min would
  // sit where the level sets of A2 and A3 touch, b = R - r + d (equal gradients in (R, b)), with
  // A2 = A3 = 2 (u - d)^2 for u = sqrt(pi r_max^2 / 4 - d^2) = 4.42 mm: R = 7.05 mm > r_max. So the
  // optimum lies on r_max^2 = (b/2)^2 + R^2, parametrised R = r_max cos(t), b = 2 r_max sin(t).
  // There the fork's A3 (~51 mm^2) is far from binding: the optimum balances the pin's A1 against
  // the knuckle's A2 (A1 rises and A2 falls with r, so A1 = A2 fixes r for each t) and takes the
  // t where that balanced area is largest (golden-section search on a unimodal function).
  const double d = 0.3 * kMm, rm = 5 * kMm;
  const auto areas = [&](double r, double t) {
    const double R = rm * std::cos(t), b = 2 * rm * std::sin(t);
    return std::array<double, 3>{2 * std::numbers::pi * (r - d) * (r - d),
                                 2 * (b - 2 * d) * (R - d - r),
                                 std::numbers::pi * rm * rm - 2 * b * (R - r + d)};
  };
  const auto r_of = [&](double t) {
    const double R = rm * std::cos(t);
    return bisect(
        [&](double r) {
          auto a = areas(r, t);
          return a[0] - a[1];
        },
        d * 1.0001, R - d);
  };
  double lo = 0.1, hi = 1.3;
  const double g = (std::sqrt(5.0) - 1) / 2;
  for (int i = 0; i < 100; ++i) {
    const double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    if (areas(r_of(x1), x1)[0] < areas(r_of(x2), x2)[0])
      lo = x1;
    else
      hi = x2;
  }
  const double t_star = 0.5 * (lo + hi);
  const double r_star = r_of(t_star);
  const auto a_star = areas(r_star, t_star);
  ASSERT_GT(a_star[2], 2 * a_star[0]);  // A3 is slack

  JointDesignOptions options;
  options.clearance_m = d;
  const HingeDesign design = design_hinge(rm, HingeRange{}, options);
  ASSERT_TRUE(design.feasible);
  EXPECT_NEAR(design.min_area, a_star[0], 2e-3 * a_star[0]);
  EXPECT_NEAR(design.areas[0], design.areas[1], 5e-3 * a_star[0]);
  EXPECT_NEAR(design.r, r_star, 1e-2 * r_star);
  EXPECT_NEAR(design.R, rm * std::cos(t_star), 1e-2 * rm);
  EXPECT_NEAR(design.b, 2 * rm * std::sin(t_star), 1e-2 * rm);
  EXPECT_NEAR(std::hypot(design.R, design.b / 2), rm, 1e-3 * rm);
}

TEST(JointDesign, HingeSwingPast90DegreesCutsTheFork) {
  const double d = 0.3 * kMm, rm = 5 * kMm, R = 3 * kMm, r = 1 * kMm, b = 3 * kMm;
  JointDesignOptions options;
  options.clearance_m = d;
  const auto none = hinge_areas(rm, R, r, b, HingeRange{}, options);
  EXPECT_NEAR(none[2], std::numbers::pi * rm * rm - 2 * b * (R - r + d), 1e-15);
  // alpha = asin((R - d - r) / (R - d)) = 47.8 deg: a 60 deg forward swing passes 90 deg and
  // removes the disc segment beyond R - d = 2.7 mm less the slot's strip b x d.
  const double y0 = R - d;
  const double segment = rm * rm * std::acos(y0 / rm) - y0 * std::sqrt(rm * rm - y0 * y0);
  const auto swung = hinge_areas(rm, R, r, b, HingeRange{60 * std::numbers::pi / 180, 0}, options);
  EXPECT_NEAR(swung[2], none[2] - (segment - b * d), 1e-15);
  EXPECT_EQ(swung[0], none[0]);
  EXPECT_EQ(swung[1], none[1]);
}

TEST(JointDesign, TooSmallForTheClearanceIsInfeasible) {
  JointDesignOptions options;
  options.clearance_m = 0.3 * kMm;
  EXPECT_FALSE(design_ball_socket(0.9 * kMm, BallRange{}, options).feasible);  // < 3.41 d
  EXPECT_FALSE(design_hinge(0.6 * kMm, HingeRange{}, options).feasible);       // < 2.24 d
}

}  // namespace
}  // namespace hc::articulation
