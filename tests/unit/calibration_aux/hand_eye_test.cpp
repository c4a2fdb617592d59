// Hand-eye (arm <-> camera rig) from tool markers: synthetic poses with known truth and noise, the
// unobservable cases of a 4-DOF arm, and OpenCV's cv::calibrateHandEye (Tsai, Park, Horaud) as a
// peer on 6-DOF poses.
#include <gtest/gtest.h>

// Eigen before OpenCV's Eigen bridge (opencv/opencv#17366).
#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include <cmath>
#include <numbers>
#include <random>

#include "calibration/arm/hand_eye.h"

namespace hc::calib {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

double rotation_error_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() / kDeg;
}

Eigen::Isometry3d truth_world_from_rig() {
  // Camera 0 about 0.35 m from the arm's origin, looking down at it (any rigid transform works).
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.linear() =
      (Eigen::AngleAxisd(2.2, Eigen::Vector3d(0.3, -0.8, 0.5).normalized())).toRotationMatrix();
  x.translation() = Eigen::Vector3d(0.31, -0.12, 0.42);
  return x;
}

struct Synthetic {
  HandEyeProblem problem;
  Eigen::Isometry3d truth;
  std::vector<Eigen::Vector3d> offsets;
};

// A 4-DOF arm at `n` poses in a box (x, y +-0.07 m, z 0.02..0.14 m, any yaw unless yaw_range = 0),
// (the rig's workspace box is +-0.1 m: a calibration uses most of it, since a rotation error of X
// moves X's translation by the lever arm from the points to camera 0, ~0.4 m here),
// two shaft markers 0.06 and 0.11 m above the tip, slightly off the axis (a bent shaft), observed
// with isotropic Gaussian noise sigma_m per coordinate (triangulation noise).
Synthetic four_dof(int n, double sigma_m, std::uint64_t seed, double yaw_range = std::numbers::pi,
                   bool fixed_z = false) {
  Synthetic s;
  s.truth = truth_world_from_rig();
  s.offsets = {{0.0008, -0.0005, 0.06}, {0.0011, 0.0004, 0.11}};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, sigma_m);
  for (int i = 0; i < n; ++i) {
    // Draws in separate statements: argument evaluation order is unspecified (g++ != clang).
    const double x = 0.07 * u(rng), y = 0.07 * u(rng);
    const double z = fixed_z ? 0.08 : 0.08 + 0.06 * u(rng);
    const double yaw = yaw_range * u(rng);
    const Eigen::Isometry3d t = arm_pose_transform(x, y, z, yaw);
    s.problem.world_from_tool.push_back(t);
    for (std::size_t j = 0; j < 2; ++j) {
      const Eigen::Vector3d p = s.truth.inverse() * (t * s.offsets[j]);
      const double nx = g(rng), ny = g(rng), nz = g(rng);
      s.problem.observations.push_back(
          {static_cast<std::size_t>(i), j, p + Eigen::Vector3d(nx, ny, nz)});
    }
  }
  s.problem.markers = 2;
  return s;
}

TEST(HandEye, FourDofArmRecoversWorldFromRigAtRealisticNoise) {
  // 100 poses, 0.05 mm triangulation noise per coordinate (the tracking target is <= 0.1 mm RMS).
  const double sigma = 0.05e-3;
  const Synthetic s = four_dof(100, sigma, 1);
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;  // the shaft marker's distance from the tip (probe geometry)
  Result<HandEyeResult> r = solve_hand_eye(s.problem, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->rotation_excitation, "single axis");
  const double t_err = (r->world_from_rig.translation() - s.truth.translation()).norm();
  const double r_err = rotation_error_deg(r->world_from_rig.linear(), s.truth.linear());
  // Brief: translation within 0.1 mm, rotation within 0.05 deg at realistic noise.
  EXPECT_LT(t_err, 0.1e-3);
  EXPECT_LT(r_err, 0.05);
  // The reported standard deviations are consistent with the actual errors (4 sigma).
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(r->world_from_rig.translation()[k], s.truth.translation()[k],
                4.0 * r->translation_std_m[k] + 1e-9);
  for (std::size_t j = 0; j < 2; ++j)
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(r->offsets_m[j][k], s.offsets[j][k], 4.0 * r->offsets_std_m[j][k] + 1e-12)
          << j << " " << k;
  // Residual RMS of a 3-D Gaussian: sigma sqrt(3) (less a little for the fitted parameters).
  EXPECT_NEAR(r->rms_m, sigma * std::sqrt(3.0), 0.15 * sigma * std::sqrt(3.0));
  EXPECT_EQ(r->outliers, 0u);
  EXPECT_TRUE(r->converged);
}

TEST(HandEye, RobustLossKeepsAccuracyWithOutliers) {
  Synthetic s = four_dof(100, 0.05e-3, 2);
  // 5 % of the observations are mismatched dots 5 mm off.
  for (std::size_t k = 0; k < s.problem.observations.size(); k += 20)
    s.problem.observations[k].p_rig_m += Eigen::Vector3d(0.005, -0.003, 0.002);
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  Result<HandEyeResult> r = solve_hand_eye(s.problem, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_LT((r->world_from_rig.translation() - s.truth.translation()).norm(), 0.1e-3);
  EXPECT_LT(rotation_error_deg(r->world_from_rig.linear(), s.truth.linear()), 0.05);
  EXPECT_EQ(r->outliers, 10u);
}

TEST(HandEye, CoplanarPosesAreEnoughForThePointForm) {
  // Every tip position at one height: the marker points still span 3-D (two marker heights, yaw),
  // so the point form needs nothing more (AX = XB would be degenerate here).
  const Synthetic s = four_dof(40, 0.05e-3, 3, std::numbers::pi, /*fixed_z=*/true);
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  Result<HandEyeResult> r = solve_hand_eye(s.problem, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_LT((r->world_from_rig.translation() - s.truth.translation()).norm(), 0.1e-3);
  EXPECT_LT(rotation_error_deg(r->world_from_rig.linear(), s.truth.linear()), 0.05);
}

TEST(HandEye, YawOnlyArmNeedsTheMarkerHeight) {
  const Synthetic s = four_dof(30, 0.05e-3, 4);
  Result<HandEyeResult> r = solve_hand_eye(s.problem, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("one axis"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("marker0_tool_z_m"), std::string::npos);
  // The wrong height shifts world_from_rig along z by exactly the error (the unobservable
  // direction), and nothing else.
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  Result<HandEyeResult> right = solve_hand_eye(s.problem, o);
  o.marker0_tool_z_m = 0.061;
  Result<HandEyeResult> shifted = solve_hand_eye(s.problem, o);
  ASSERT_TRUE(right.ok());
  ASSERT_TRUE(shifted.ok());
  const Eigen::Vector3d d =
      shifted->world_from_rig.translation() - right->world_from_rig.translation();
  EXPECT_NEAR(d.z(), 0.001, 1e-8);
  EXPECT_LT(d.head<2>().norm(), 1e-8);
  EXPECT_LT(rotation_error_deg(shifted->world_from_rig.linear(), right->world_from_rig.linear()),
            1e-6);
  EXPECT_NEAR(shifted->rms_m, right->rms_m, 1e-9);
}

TEST(HandEye, PureTranslationNeedsAKnownOffset) {
  const Synthetic s = four_dof(30, 0.05e-3, 5, /*yaw_range=*/0.0);
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  Result<HandEyeResult> r = solve_hand_eye(s.problem, o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("pure translation"), std::string::npos);
  // With marker 0's whole offset known, everything else is observable again.
  HandEyeOptions k;
  k.known_offsets_m = {s.offsets[0], std::nullopt};
  Result<HandEyeResult> ok = solve_hand_eye(s.problem, k);
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  EXPECT_LT((ok->world_from_rig.translation() - s.truth.translation()).norm(), 0.1e-3);
  EXPECT_LT((ok->offsets_m[1] - s.offsets[1]).norm(), 0.1e-3);
}

TEST(HandEye, CollinearObservationsAreRefused) {
  // The arm moves only along z and the markers sit on the axis: every point on one line.
  Synthetic s;
  s.truth = truth_world_from_rig();
  for (int i = 0; i < 10; ++i) {
    const Eigen::Isometry3d t = arm_pose_transform(0.0, 0.0, 0.02 + 0.01 * i, 0.3 * i);
    s.problem.world_from_tool.push_back(t);
    for (std::size_t j = 0; j < 2; ++j)
      s.problem.observations.push_back(
          {static_cast<std::size_t>(i), j,
           s.truth.inverse() * (t * Eigen::Vector3d(0, 0, j == 0 ? 0.06 : 0.11))});
  }
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  Result<HandEyeResult> r = solve_hand_eye(s.problem, o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("collinear"), std::string::npos) << r.status().message();
}

TEST(HandEye, BadInput) {
  Synthetic s = four_dof(10, 0.0, 6);
  HandEyeOptions o;
  o.marker0_tool_z_m = 0.06;
  HandEyeProblem p = s.problem;
  p.observations[3].pose = 99;
  EXPECT_EQ(solve_hand_eye(p, o).status().code(), StatusCode::kInvalidArgument);
  p = s.problem;
  p.observations[2].p_rig_m.x() = std::nan("");
  EXPECT_EQ(solve_hand_eye(p, o).status().code(), StatusCode::kInvalidArgument);
  p = s.problem;
  p.world_from_tool[1].linear() *= 1.1;  // not a rotation
  EXPECT_EQ(solve_hand_eye(p, o).status().code(), StatusCode::kInvalidArgument);
  p = s.problem;
  p.observations.resize(3);
  EXPECT_EQ(solve_hand_eye(p, o).status().code(), StatusCode::kFailedPrecondition);
  o.huber_m = 0.0;
  EXPECT_EQ(solve_hand_eye(s.problem, o).status().code(), StatusCode::kInvalidArgument);
}

// ---- Peer: OpenCV's AX = XB solvers on a 6-DOF arm carrying a 4-marker target ----

TEST(HandEye, AgreesWithOpenCvCalibrateHandEyeOnSixDofPoses) {
  const Eigen::Isometry3d truth = truth_world_from_rig();
  // Target geometry in its own frame and its unknown mounting on the tool (target -> tool).
  const std::vector<Eigen::Vector3d> target = {
      {0, 0, 0}, {0.04, 0, 0}, {0, 0.03, 0}, {0.01, 0.02, 0.025}};
  Eigen::Isometry3d tool_from_target = Eigen::Isometry3d::Identity();
  tool_from_target.linear() =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  tool_from_target.translation() = Eigen::Vector3d(0.01, -0.02, 0.08);

  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double sigma = 0.05e-3;
  std::normal_distribution<double> g(0.0, sigma);
  HandEyeProblem problem;
  problem.markers = target.size();
  std::vector<cv::Mat> r_base2gripper, t_base2gripper, r_target2cam, t_target2cam;
  for (int i = 0; i < 30; ++i) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    // Yaw within +-60 deg: Tsai's method degenerates for relative rotations near 180 deg.
    const double rz = u(rng), rx = u(rng), ry = u(rng);
    t.linear() = (Eigen::AngleAxisd(std::numbers::pi / 3.0 * rz, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(0.5 * rx, Eigen::Vector3d::UnitX()) *
                  Eigen::AngleAxisd(0.5 * ry, Eigen::Vector3d::UnitY()))
                     .toRotationMatrix();
    const double tx = u(rng), ty = u(rng), tz = u(rng);
    t.translation() = Eigen::Vector3d(0.05 * tx, 0.05 * ty, 0.07 + 0.04 * tz);
    problem.world_from_tool.push_back(t);
    Eigen::Matrix3Xd src(3, 4), dst(3, 4);
    for (std::size_t j = 0; j < target.size(); ++j) {
      const Eigen::Vector3d p = truth.inverse() * (t * (tool_from_target * target[j])) +
                                Eigen::Vector3d(g(rng), g(rng), g(rng));
      problem.observations.push_back({static_cast<std::size_t>(i), j, p});
      src.col(static_cast<Eigen::Index>(j)) = target[j];
      dst.col(static_cast<Eigen::Index>(j)) = p;
    }
    // The target's pose in the camera (rig) frame from its markers, as a camera would give it.
    const Eigen::Matrix4d cam_from_target = Eigen::umeyama(src, dst, false);
    const Eigen::Isometry3d base2gripper = t.inverse();
    cv::Mat r, tr, rt, tt;
    cv::eigen2cv(Eigen::Matrix3d(base2gripper.linear()), r);
    cv::eigen2cv(Eigen::Vector3d(base2gripper.translation()), tr);
    cv::eigen2cv(Eigen::Matrix3d(cam_from_target.topLeftCorner<3, 3>()), rt);
    cv::eigen2cv(Eigen::Vector3d(cam_from_target.topRightCorner<3, 1>()), tt);
    r_base2gripper.push_back(r);
    t_base2gripper.push_back(tr);
    r_target2cam.push_back(rt);
    t_target2cam.push_back(tt);
  }
  Result<HandEyeResult> ours = solve_hand_eye(problem, {});
  ASSERT_TRUE(ours.ok()) << ours.status().to_string();
  EXPECT_EQ(ours->rotation_excitation, "multiple axes");
  const double our_t = (ours->world_from_rig.translation() - truth.translation()).norm();
  const double our_r = rotation_error_deg(ours->world_from_rig.linear(), truth.linear());
  EXPECT_LT(our_t, 0.1e-3);
  EXPECT_LT(our_r, 0.05);
  // Eye-to-hand with OpenCV: pass base->gripper instead of gripper->base; the "cam2gripper"
  // result is then cam -> base, i.e. world_from_rig.
  for (const auto method :
       {cv::CALIB_HAND_EYE_TSAI, cv::CALIB_HAND_EYE_PARK, cv::CALIB_HAND_EYE_HORAUD}) {
    cv::Mat r, tr;
    cv::calibrateHandEye(r_base2gripper, t_base2gripper, r_target2cam, t_target2cam, r, tr, method);
    Eigen::Matrix3d re;
    Eigen::Vector3d te;
    cv::cv2eigen(r, re);
    cv::cv2eigen(tr, te);
    const double cv_t = (te - truth.translation()).norm();
    const double cv_r = rotation_error_deg(re, truth.linear());
    // OpenCV's AX = XB solvers are close to the truth too (sub-mm, sub-0.1 deg at this noise)
    // and agree with ours; ours, using every marker directly, is at least as accurate.
    EXPECT_LT(cv_t, 1e-3) << "method " << static_cast<int>(method);
    EXPECT_LT(cv_r, 0.1) << "method " << static_cast<int>(method);
    EXPECT_LT((te - ours->world_from_rig.translation()).norm(), 1e-3);
    EXPECT_LE(our_t, cv_t + 0.02e-3) << "method " << static_cast<int>(method);
    RecordProperty("opencv_method_" + std::to_string(static_cast<int>(method)) + "_t_err_mm",
                   std::to_string(cv_t * 1e3));
  }
  RecordProperty("ours_t_err_mm", std::to_string(our_t * 1e3));
}

}  // namespace
}  // namespace hc::calib
