// Joints from motion (beyond the thesis, which left joint types, hinge axes and ranges to the
// user): from a file's animation clips, the rigid motion of each link's skinned vertices gives the
// relative rotation of a joint's two links over every frame. Rotation vectors confined to one axis
// make a hinge with that axis; otherwise a ball-and-socket with the observed cone; links that
// never move relative to each other are fused. The rotation centre is the least-squares point that
// moves the same with both links (the centre-of-rotation fit of gait analysis, Ehrig et al. 2006's
// SCoRE), pulled towards a prior centre along directions the motion leaves free (a hinge's axis).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "common/status.h"
#include "fabrication/articulation/skinned_character.h"

namespace hc::articulation {

// Rigid transform (rest pose -> posed, model frame) of every bone at every frame of every clip,
// fitted (Kabsch) to the bone's core vertices: those whose weight for it is at least
// core_weight, or, when fewer than 4, those it dominates. Bones with fewer than 3 usable vertices
// follow their skinning transform (scale removed).
struct LinkMotion {
  // [clip][frame][bone]
  std::vector<std::vector<std::vector<Eigen::Isometry3d>>> transforms;
  double max_fit_rms_m = 0.0;  // worst rms distance of core vertices from their rigid fit
};

struct MotionOptions {
  double core_weight = 0.9;
  // A joint whose relative rotation never exceeds this in any frame is fused.
  double fused_below_rad = 1.0 * 3.14159265358979 / 180;
  // Hinge when the rms of the rotation vectors' off-axis part is below both this fraction of the
  // rms along the axis and the absolute limit below.
  double hinge_off_axis_fraction = 0.2;
  double hinge_off_axis_rad = 5.0 * 3.14159265358979 / 180;
  // A motion axis closer than this to the joint's orientation n is a twist, which a ball (free
  // about n) already allows: classified as ball.
  double twist_axis_within_rad = 30.0 * 3.14159265358979 / 180;
  // Smallest rank-deficiency singular value ratio treated as free (pseudo-inverse cut-off).
  double centre_singular_cutoff = 0.05;
  Status validate() const;
};

Result<LinkMotion> fit_link_motion(const SkinnedCharacter& character, const MotionOptions& options);

enum class MotionJointType { kFused, kHinge, kBall };

struct MotionEstimate {
  MotionJointType type = MotionJointType::kFused;
  std::vector<std::string> clips;  // clips in which the joint moved
  int frames = 0;                  // frames used, over all clips
  double max_angle_rad = 0.0;      // largest relative rotation seen
  // Hinge: the rotation axis (unit, model frame at rest), forward/backward swing observed
  // (positive rotation about the axis is forward).
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();
  double swing_forward_rad = 0.0;
  double swing_backward_rad = 0.0;
  double off_axis_rms_rad = 0.0;
  double on_axis_rms_rad = 0.0;
  // Ball: largest tilt of n seen, and the principal tilt direction (unit, perpendicular to n) with
  // the largest tilts along it and across it (an elliptical cone covering every frame).
  Eigen::Vector3d tilt_direction = Eigen::Vector3d::Zero();
  double cone_major_rad = 0.0;
  double cone_minor_rad = 0.0;
  // Least-squares centre of rotation (model frame, m) and its rms residual over the frames.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double centre_rms_m = 0.0;
  int centre_free_directions = 0;  // 1 for a hinge (along its axis), 3 when nothing moved
};

// The motion of link `child` relative to link `parent` over every clip. `n` is the joint's
// orientation (parent -> child, unit), `prior_centre` the centre to keep along free directions.
MotionEstimate estimate_joint_motion(const LinkMotion& motion, int parent, int child,
                                     const Eigen::Vector3d& n,
                                     const Eigen::Vector3d& prior_centre,
                                     const std::vector<Clip>& clips, const MotionOptions& options);

// Rotation vector (axis * angle, |angle| <= pi) of a rotation matrix.
Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& r);

}  // namespace hc::articulation
