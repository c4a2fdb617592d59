// The project's one camera model: calibration estimates it, tracking uses it, the simulator
// renders with it. OpenCV's pinhole model with its distortion coefficients, extrinsics, the rig
// calibration file (YAML that OpenCV's cv::FileStorage reads) and the readers of a camera from a
// config map (rig YAML) and from JSON (a session's "sim_cameras" metadata).
//
//   x_c = R X + t;  (x, y) = (x_c / z_c, y_c / z_c);  r^2 = x^2 + y^2
//   x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
//   u = fx x' + cx;  v = fy y' + cy
// (OpenCV "Camera Calibration and 3D Reconstruction", calib3d.) Camera frame: x right, y down, z
// forward.
//
// Frames: a point X in the reference frame maps to the camera frame as x_cam = R * X + t. For a
// calibrated rig the reference is the rig frame, the first camera's frame after `hardcopy calib
// cameras`; `world_from_rig` (identity until a hand-eye calibration sets it) takes rig coordinates
// to the arm's / specimen's world frame. For the simulator's cameras it is the world frame.
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

#include "common/config.h"
#include "common/json.h"
#include "common/status.h"

namespace hc {

struct CameraModel {
  std::string name;
  int width = 0;  // image size, px
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  // px
  // OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6]] — 0, 4, 5 or 8 values.
  std::vector<double> distortion;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // reference (rig) -> camera rotation
  Eigen::Vector3d t_m = Eigen::Vector3d::Zero();    // reference (rig) -> camera translation, m
  double rms_px = 0.0;  // reprojection RMS of the calibration that produced it (0: unknown)

  Eigen::Matrix3d K() const;
  // 3x4 projection matrix K [R | t] of undistorted pixels.
  Eigen::Matrix<double, 3, 4> projection() const;
  // The rigid transform from the reference (rig) frame to the camera frame: (R, t).
  Eigen::Isometry3d camera_from_reference() const;
  // Camera centre in the reference frame.
  Eigen::Vector3d center_m() const { return -R.transpose() * t_m; }
  // Depth z_c of a reference-frame point in front of the camera, m.
  double depth_m(const Eigen::Vector3d& x_rig_m) const { return R.row(2).dot(x_rig_m) + t_m.z(); }
  // Pixel of a rig-frame point (with distortion); nullopt behind the camera (z <= 0).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& x_rig_m) const;
  // Distorts a normalised image point (x/z, y/z) to pixels.
  Eigen::Vector2d distort_normalized(const Eigen::Vector2d& xn) const;
  // Inverse of distort_normalized (Newton; converges for the distortions of real lenses inside
  // the image, also strong barrel distortion near the corners).
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

// Sets R and t of a camera at `position` looking at `target` with image "up" towards +z (or +y
// when looking straight down).
void look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target, CameraModel& camera);

// Reads a camera from a config map (a rig YAML's camera device): width, height, fx, fy, cx, cy
// (default: the image centre), distortion [k1, k2, p1, p2[, k3[, k4, k5, k6]]], and either R (3x3
// rows) + t [m] or position_m + look_at_m. Keys not given keep `camera`'s values. Errors name the
// file, line and key.
Status read_camera(ConfigNode node, CameraModel& camera);

// A camera as JSON: width, height, fx, fy, cx, cy, distortion, R (3 rows), t_m and center_m (for
// readers; ignored on input). camera_from_json reads it back: kInvalidArgument naming `where` and
// the key when something is missing, of the wrong type or fails validate().
Json camera_to_json(const CameraModel& camera);
Result<CameraModel> camera_from_json(const Json& j, const std::string& name,
                                     std::string_view where);

}  // namespace hc
