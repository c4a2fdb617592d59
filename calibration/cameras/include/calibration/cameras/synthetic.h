// Synthetic calibration rigs with known truth, for tests and benchmarks: cameras on a half circle
// looking at a common point, random board poses that several cameras see from the front, and
// exact (optionally noisy) corner observations. Images come from ChessboardRenderer (board.h).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

#include "calibration/cameras/board.h"
#include "calibration/cameras/calibrate.h"
#include "camera/camera_model.h"

namespace hc::calib {

struct SyntheticRigOptions {
  int cameras = 3;
  int width = 1600;
  int height = 1200;
  double radius_m = 1.0;       // distance of every camera from the common look-at point
  double arc_deg = 180.0;      // cameras spread evenly over this arc (azimuth)
  double elevation_deg = 0.0;  // every camera this far above the look-at point's horizontal
  double focal_px = 1800.0;    // camera i gets focal_px * (1 + 0.01 i), fy 0.2 % above fx
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

struct BoardPoseOptions {
  int count = 30;
  std::uint32_t seed = 1;
  int min_cameras = 2;  // each pose is seen by at least this many cameras (board_visible)
  // Board centre uniformly within +-offset_m of the look-at point (world x, y, z; y down).
  Eigen::Vector3d offset_m = Eigen::Vector3d::Constant(0.1);
  // The board faces a random direction on the cameras' arc, then tilts: per_axis_tilt draws
  // rotations about its x and y axes uniformly within +-max_tilt_deg each (so many poses are
  // nearly frontal); otherwise the tilt angle is uniform in [min_tilt_deg, max_tilt_deg] about a
  // random axis in the board plane. Then a spin about its normal within +-spin_deg.
  bool per_axis_tilt = false;
  double min_tilt_deg = 0.0;
  double max_tilt_deg = 35.0;
  double spin_deg = 20.0;
  double max_view_angle_deg = 60.0;  // board_visible's limit
  // > 0: keep only poses whose cameras are within this many consecutive cameras (6 of 7: cameras
  // 0 and 6 never see the board together).
  int max_camera_span = 0;
};
std::vector<Eigen::Isometry3d> random_board_poses(const std::vector<CameraModel>& rig,
                                                  const BoardSpec& board,
                                                  const BoardPoseOptions& options);

// The product's capture geometry, for the calibration accuracy tests and the benchmark:
// rig_daemon/examples/rig_sim_hires.yaml (after thesis Sec. 5.6: seven 1600 x 1200 cameras on a
// half circle above a ~50 mm specimen): cameras 0.294 m from the look-at point on a half circle
// 41.6 deg above it (0.22 m from the axis, 0.195 m up), f = 3500 px (+1 % per camera, fy 0.2 %
// above fx), distortion as its cam0 (k3 = 0).
SyntheticRigOptions capture_rig_options(int cameras);
// A board sized for that view (0.137 x 0.103 m at 0.294 m): a chessboard of 15 x 10 inner corners,
// 5 mm squares (70 x 45 mm between the outer corners, 90 x 65 mm with the quiet zone that
// board_visible checks; an A6 card); cols + rows odd, so its corner order is unambiguous.
BoardSpec capture_board();
// Poses through that working volume: board centre within +-20 mm of the look-at point, tilted
// 20-50 deg from facing a camera (focal length / depth decorrelation), cameras drawn uniformly.
BoardPoseOptions capture_board_poses(int count, std::uint32_t seed);

// Recovered camera centres against the truth (both in camera 0's frame), m.
struct CentreErrors {
  // Worst |c - c_true| as calibrated: relative to camera 0, so an error in camera 0's own
  // orientation (or principal point) swings every other centre about it.
  double raw_m = 0.0;
  // Worst error after the best rigid alignment of all recovered centres onto the true ones
  // (Umeyama, no scale: the board fixes the scale): the gauge-free error of the rig's shape.
  // With fewer than 3 cameras no alignment is made (aligned = raw).
  double aligned_m = 0.0;
  // The aligned error split along each true optical axis (depth, tied to the focal length) and
  // across it; worst over the cameras.
  double aligned_axial_m = 0.0;
  double aligned_lateral_m = 0.0;
  std::vector<double> aligned_per_camera_m;
};
CentreErrors compare_centres(const std::vector<CameraModel>& truth,
                             const std::vector<CameraModel>& got);

// Projections of every visible board corner (board_visible) plus Gaussian noise of sigma noise_px
// per coordinate; view numbers are pose indices.
std::vector<CameraObservations> synthetic_observations(const std::vector<CameraModel>& rig,
                                                       const BoardSpec& board,
                                                       const std::vector<Eigen::Isometry3d>& poses,
                                                       double noise_px, std::uint32_t seed);

}  // namespace hc::calib
