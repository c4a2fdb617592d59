// The analytic specimen against closed-form contact mechanics.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "rig_daemon/simulation/specimen.h"

namespace hc::devices::sim {
namespace {

HertzSpecimen::Options pure_hertz() {
  HertzSpecimen::Options o;
  o.youngs_modulus_pa = 1.0e6;
  o.poisson_ratio = 0.45;
  o.stiffening = 0.0;
  return o;
}

Indentation at_center(double depth_m, double radius_m = 0.005) {
  Indentation ind;
  ind.depth_m = depth_m;
  ind.probe_radius_m = radius_m;
  return ind;
}

TEST(HertzSpecimen, ForceIsHertzSphereOnHalfSpace) {
  const HertzSpecimen s(pure_hertz());
  // Hertz: F = 4/3 E* sqrt(R) d^(3/2), E* = E / (1 - nu^2) for a rigid sphere (K. L. Johnson,
  // Contact Mechanics, 1985, §4.2). E = 1 MPa, nu = 0.45, R = 5 mm, d = 1 mm:
  // E* = 1e6 / 0.7975 = 1.2539185e6 Pa; F = 4/3 * 1.2539185e6 * 0.070710678 * 3.1622777e-5
  //    = 3.73846 N.
  EXPECT_NEAR(s.effective_modulus_pa(), 1.2539185e6, 1.0);
  EXPECT_NEAR(s.force_n(at_center(0.001)), 3.73846, 1e-5);
  for (double d : {1e-5, 1e-4, 5e-4, 2e-3, 4e-3}) {
    const double expected = 4.0 / 3.0 * 1.2539185e6 * std::sqrt(0.005) * std::pow(d, 1.5);
    EXPECT_NEAR(s.force_n(at_center(d)), expected, 1e-6 * expected) << d;
  }
  // F ∝ d^(3/2): doubling the depth multiplies the force by 2^1.5.
  EXPECT_NEAR(s.force_n(at_center(0.002)) / s.force_n(at_center(0.001)), std::pow(2.0, 1.5), 1e-9);
  EXPECT_EQ(s.force_n(at_center(0.0)), 0.0);
  EXPECT_EQ(s.force_n(at_center(-0.001)), 0.0);
}

TEST(HertzSpecimen, HiddenStiffeningScalesTheHertzForce) {
  HertzSpecimen::Options o = pure_hertz();
  const HertzSpecimen plain(o);
  o.stiffening = 0.5;
  const HertzSpecimen stiff(o);
  for (double d : {1e-4, 1e-3, 3e-3}) {
    EXPECT_NEAR(stiff.force_n(at_center(d)) / plain.force_n(at_center(d)), 1.0 + 0.5 * d / 0.005,
                1e-12);
  }
  // Thesis 5.6 range: the default specimen reaches 35-50 N within 5 mm of indentation.
  const HertzSpecimen defaults(HertzSpecimen::Options{});
  EXPECT_GT(defaults.force_n(at_center(0.005)), 50.0);
  EXPECT_LT(defaults.force_n(at_center(0.003)), 35.0);
}

TEST(HertzSpecimen, NoForceOutsideTheFootprint) {
  const HertzSpecimen s(pure_hertz());
  Indentation ind = at_center(0.001);
  ind.center_x_m = 0.031;  // the block is 60 mm wide, centred on 0
  EXPECT_EQ(s.force_n(ind), 0.0);
  EXPECT_EQ(s.displacement({0.031, 0.0, s.top_z_m()}, ind).norm(), 0.0);
}

TEST(HertzSpecimen, SurfaceDisplacementMatchesHertzAndBoussinesq) {
  const HertzSpecimen s(pure_hertz());
  const double R = 0.005, d = 0.001, a = std::sqrt(R * d);
  const Indentation ind = at_center(d, R);
  const double z = s.top_z_m();
  // Under the probe the surface follows the sphere: u_z(0) = -d, u_z(r) = -(d - r^2 / (2R)) + ...
  // exactly u_z = -(2a^2 - r^2) / (2R) (Johnson §3.4) which is the sphere shifted by d.
  EXPECT_NEAR(s.displacement({0.0, 0.0, z}, ind).z(), -d, 1e-12);
  EXPECT_NEAR(s.displacement({0.5 * a, 0.0, z}, ind).z(), -(d - 0.25 * a * a / (2.0 * R)), 1e-12);
  // Continuous at the contact edge: u_z(a) = -a^2 / (2R) = -d / 2 from both sides.
  EXPECT_NEAR(s.displacement({a * (1 - 1e-9), 0.0, z}, ind).z(), -d / 2.0, 1e-9);
  EXPECT_NEAR(s.displacement({a * (1 + 1e-9), 0.0, z}, ind).z(), -d / 2.0, 1e-9);
  // Far from the contact the surface sees a point load P = F_Hertz (Boussinesq; Johnson §3.2):
  //   u_z = -(1 - nu^2) P / (pi E r),  u_r = -(1 - 2 nu)(1 + nu) P / (2 pi E r).
  const double E = 1.0e6, nu = 0.45;
  const double P = s.force_n(ind);
  const double r = 20.0 * a;
  const Eigen::Vector3d u = s.displacement({0.0, r, z}, ind);
  const double uz_point = -(1 - nu * nu) * P / (std::numbers::pi * E * r);
  const double ur_point = -(1 - 2 * nu) * (1 + nu) * P / (2 * std::numbers::pi * E * r);
  EXPECT_NEAR(u.z(), uz_point, 2e-3 * std::abs(uz_point));  // O((a/r)^2) difference
  EXPECT_NEAR(u.y(), ur_point, 1e-9 * std::abs(ur_point));  // exact outside the contact
  EXPECT_NEAR(u.x(), 0.0, 1e-15);
  // Radial displacement points towards the axis, in the direction of the point.
  const Eigen::Vector3d diag = s.displacement({0.003, 0.003, z}, ind);
  EXPECT_LT(diag.x(), 0.0);
  EXPECT_NEAR(diag.x(), diag.y(), 1e-15);
}

TEST(HertzSpecimen, MarkersFormA3mmGridOnTheTopSurface) {
  const HertzSpecimen s(pure_hertz());
  // 60 mm / 3 mm = 20 intervals: 21 x 21 dots, both edges included.
  ASSERT_EQ(s.rest_markers().size(), 441u);
  EXPECT_NEAR(s.rest_markers()[1].x() - s.rest_markers()[0].x(), 0.003, 1e-12);
  EXPECT_NEAR(s.rest_markers()[21].y() - s.rest_markers()[0].y(), 0.003, 1e-12);
  EXPECT_NEAR(s.rest_markers()[0].x(), -0.03, 1e-12);
  for (const auto& m : s.rest_markers()) EXPECT_EQ(m.z(), s.top_z_m());
}

TEST(HertzSpecimen, OptionsAreValidated) {
  HertzSpecimen::Options o;
  EXPECT_TRUE(o.validate().ok());
  o.poisson_ratio = 0.5;
  EXPECT_EQ(o.validate().code(), StatusCode::kInvalidArgument);
  o = {};
  o.marker_radius_m = 0.002;  // dots would touch at 3 mm spacing
  EXPECT_EQ(o.validate().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::devices::sim
