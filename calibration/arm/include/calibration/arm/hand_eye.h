// Hand-eye calibration of the arm against the camera rig from markers on the tool (the contact
// probe's two shaft markers, thesis Sec. 4.4.1): the arm reports the tool pose T_i (world <- tool)
// at poses i, the cameras triangulate marker j at p_ij in the rig frame (camera 0's frame). With
// X = world_from_rig and o_j the markers' fixed offsets in the tool frame,
//     X p_ij = T_i o_j   for every observation.
// We estimate X and the o_j jointly (point-based hand-eye; unlike the classic AX = XB form it needs
// no per-pose target orientation, so two markers on a shaft suffice):
//  1. initial guess by alternation: X = Eigen::umeyama(p_ij -> T_i o_j) over all observations,
//     then o_j = mean_i T_i^-1 X p_ij (with the known components held), a few rounds;
//  2. Ceres refinement of the rig-frame residual p_ij - X^-1 T_i o_j over all observations with a
//     Huber loss (scale huber_m), the rotation as a small world-frame perturbation of the initial
//     guess (so its covariance is the rotation uncertainty in rad about the world axes);
//     observations past 3 huber_m are dropped and the problem solved once more;
//  3. standard deviations from the covariance scaled by the residual variance.
//
// Observability (what the poses must excite), checked before solving:
//  * rotations: the relative rotations R_0^T R_i. With none (pure translation), the offsets are
//    indistinguishable from X's translation: marker 0's offset must be known (known_offsets).
//  * a single rotation axis (a 4-DOF arm rotates only in yaw, about tool z): a shift of every
//    offset along the axis is indistinguishable from a shift of X along it, so marker 0's tool-z
//    must be known (marker0_tool_z_m or known_offsets) — e.g. the marker's distance from the tip
//    along a vertical shaft. This is the SCARA case of the hand-eye literature.
//  * positions: the world points T_i o_j must not be collinear (then X's rotation about that line
//    is free). Coplanar points are fine for this point-based form (they are not for AX = XB,
//    which needs two non-parallel rotation axes).
// Anything else that leaves the Jacobian rank-deficient is caught by the covariance computation
// (kFailedPrecondition naming the problem).
// Units: m, rad.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

#include "common/json.h"
#include "common/status.h"

namespace hc::calib {

struct HandEyeObservation {
  std::size_t pose = 0;    // index into world_from_tool
  std::size_t marker = 0;  // marker index (0: the one whose offset constraints apply)
  Eigen::Vector3d p_rig_m = Eigen::Vector3d::Zero();
};

struct HandEyeProblem {
  std::vector<Eigen::Isometry3d> world_from_tool;  // arm poses T_i
  std::vector<HandEyeObservation> observations;
  std::size_t markers = 2;
};

struct HandEyeOptions {
  // Offsets known from the tool's geometry, per marker (empty, or `markers` entries; nullopt =
  // unknown). A known offset is held fixed.
  std::vector<std::optional<Eigen::Vector3d>> known_offsets_m;
  // Marker 0's offset along tool z (the yaw axis of a 4-DOF arm); its x, y stay free.
  std::optional<double> marker0_tool_z_m;
  double huber_m = 0.5e-3;  // robust loss scale (a few times the triangulation noise)
  int max_iterations = 100;
  int alternation_rounds = 20;
  // Relative rotations smaller than this count as none (rad).
  double min_rotation_rad = 1e-3;
  // Positions whose second principal spread is below this are collinear (m).
  double min_spread_m = 1e-3;
  Status validate() const;
};

struct HandEyeResult {
  Eigen::Isometry3d world_from_rig = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> offsets_m;                      // tool frame, per marker
  std::vector<Eigen::Vector3d> offsets_std_m;                  // per marker (0 for held components)
  Eigen::Vector3d rotation_std_rad = Eigen::Vector3d::Zero();  // about the world axes
  Eigen::Vector3d translation_std_m = Eigen::Vector3d::Zero();
  double rms_m = 0.0;  // RMS of |p_ij - X^-1 T_i o_j| over the inliers (<= 3 huber_m)
  double max_m = 0.0;
  double initial_rms_m = 0.0;  // after the alternation (closed form)
  std::size_t observations = 0;
  std::size_t poses = 0;
  std::size_t outliers = 0;         // residual > 3 huber_m
  std::string rotation_excitation;  // "none", "single axis", "multiple axes"
  std::string constraint;           // which components were held and why
  int iterations = 0;
  bool converged = false;
  double time_s = 0.0;
  Json to_json() const;
};

// kInvalidArgument: bad options, indices out of range, non-finite values, non-rigid poses.
// kFailedPrecondition: too few observations, or the poses leave a component unobservable (the
// message says which and what to give).
Result<HandEyeResult> solve_hand_eye(const HandEyeProblem& problem,
                                     const HandEyeOptions& options = {});

// T (world <- tool) of a 4-DOF arm pose: translation (x, y, z), rotation yaw about z.
Eigen::Isometry3d arm_pose_transform(double x_m, double y_m, double z_m, double yaw_rad);

}  // namespace hc::calib
