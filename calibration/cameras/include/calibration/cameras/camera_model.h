// The calibrated camera model shared by calibration (which writes it) and tracking (which reads
// it): OpenCV's pinhole model with its distortion coefficients, extrinsics in the rig frame, and
// the rig calibration file (YAML that OpenCV's cv::FileStorage reads).
//
// Frames: a point X in the rig frame maps to the camera frame as x_cam = R * X + t. The rig frame
// is the first camera's frame after `hardcopy calib cameras`; `world_from_rig` (identity until a
// hand-eye calibration sets it) takes rig coordinates to the arm's / specimen's world frame.
// Lengths in metres, image coordinates in pixels with (0, 0) at the centre of the top-left pixel
// (OpenCV's convention).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace hc::calib {

struct CameraModel {
  std::string name;
  int width = 0;  // image size, px
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  // px
  // OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6]] — 0, 4, 5 or 8 values.
  std::vector<double> distortion;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // rig -> camera rotation
  Eigen::Vector3d t_m = Eigen::Vector3d::Zero();    // rig -> camera translation, m
  double rms_px = 0.0;  // reprojection RMS of the calibration that produced it (0: unknown)

  Eigen::Matrix3d K() const;
  // 3x4 projection matrix K [R | t] of undistorted pixels.
  Eigen::Matrix<double, 3, 4> projection() const;
  // Camera centre in the rig frame.
  Eigen::Vector3d center_m() const { return -R.transpose() * t_m; }
  // Pixel of a rig-frame point (with distortion); nullopt behind the camera (z <= 0).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& x_rig_m) const;
  // Distorts a normalised image point (x/z, y/z) to pixels.
  Eigen::Vector2d distort_normalized(const Eigen::Vector2d& xn) const;
  // Inverse of distort_normalized by fixed-point iteration (as cv::undistortPoints; converges for
  // the distortions of real lenses inside the image).
  Eigen::Vector2d undistort_to_normalized(const Eigen::Vector2d& pixel) const;
  // Unit ray direction in the rig frame through a (distorted) pixel.
  Eigen::Vector3d ray_rig(const Eigen::Vector2d& pixel) const;
};

struct RigCalibration {
  std::vector<CameraModel> cameras;
  double joint_rms_px = 0.0;  // of the joint adjustment (0: single cameras only)
  Eigen::Isometry3d world_from_rig = Eigen::Isometry3d::Identity();

  const CameraModel* find(std::string_view name) const;
};

// Writes a rig calibration as OpenCV FileStorage YAML ("%YAML:1.0"): camera_names (sequence),
// joint_rms_px, world_from_rig (4x4 !!opencv-matrix) and per camera a map under its name with
// image_width, image_height, camera_matrix (3x3), distortion_coefficients (1xN), R (3x3), t (3x1,
// m), rms_px. Atomic (temp file + rename): nothing half-written on error.
Status write_rig_calibration(const std::filesystem::path& path, const RigCalibration& rig);
// Reads what write_rig_calibration writes (and files OpenCV itself wrote in that layout), with
// yaml-cpp through common/config rather than OpenCV's parser (which never returns on some
// malformed input). kInvalidArgument naming the file, line and key on anything missing, malformed
// or not finite; camera names must be unique, non-empty and not one of the top-level keys, K
// positive, R a rotation.
Result<RigCalibration> read_rig_calibration(const std::filesystem::path& path);
// Validates one model (sizes, positive focal lengths, finite values, R orthonormal with det +1,
// distortion count 0/4/5/8); the message names the camera.
Status validate(const CameraModel& camera);

}  // namespace hc::calib
