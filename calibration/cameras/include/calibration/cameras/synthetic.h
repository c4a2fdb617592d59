// Synthetic calibration rigs with known truth, for tests and benchmarks: cameras on a half circle
// looking at a common point, random board poses that several cameras see from the front, and
// exact (optionally noisy) corner observations. Images come from ChessboardRenderer (board.h).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

#include "calibration/cameras/board.h"
#include "calibration/cameras/calibrate.h"
#include "calibration/cameras/camera_model.h"

namespace hc::calib {

struct SyntheticRigOptions {
  int cameras = 3;
  int width = 1600;
  int height = 1200;
  double radius_m = 1.0;     // distance of every camera from the common look-at point
  double arc_deg = 180.0;    // cameras spread evenly over this arc
  double focal_px = 1800.0;  // camera i gets focal_px * (1 + 0.01 i), fy 0.2 % above fx
  std::vector<double> distortion = {-0.12, 0.08, 0.0004, -0.0003, -0.02};
};

// Camera i is named "cam<i>"; poses are given relative to camera 0 (the rig frame of a
// calibration), so the truth compares directly with calibrate_rig's output.
std::vector<CameraModel> make_half_circle_rig(const SyntheticRigOptions& options);

// The look-at point of make_half_circle_rig's cameras in the rig frame.
Eigen::Vector3d rig_look_at(const std::vector<CameraModel>& rig);

// True when every corner of the board projects inside the image (margin in px) and the camera sees
// the board's front at most max_angle_deg away from its normal.
bool board_visible(const CameraModel& camera, const BoardSpec& board,
                   const Eigen::Isometry3d& rig_from_board, double max_angle_deg = 60.0,
                   double margin_px = 30.0);

// `count` random board poses around the look-at point (centre within +-offset_m, tilt within
// +-tilt_deg, facing a random direction on the rig's arc), each seen by at least min_cameras.
std::vector<Eigen::Isometry3d> random_board_poses(const std::vector<CameraModel>& rig,
                                                  const BoardSpec& board, int count,
                                                  std::uint32_t seed, int min_cameras = 2,
                                                  double offset_m = 0.1, double tilt_deg = 35.0);

// Projections of every visible board corner (board_visible) plus Gaussian noise of sigma noise_px
// per coordinate; view numbers are pose indices.
std::vector<CameraObservations> synthetic_observations(const std::vector<CameraModel>& rig,
                                                       const BoardSpec& board,
                                                       const std::vector<Eigen::Isometry3d>& poses,
                                                       double noise_px, std::uint32_t seed);

}  // namespace hc::calib
