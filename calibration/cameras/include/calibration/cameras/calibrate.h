// Camera calibration from board observations: single-camera intrinsics (OpenCV's
// calibrateCamera, used as the initial guess and as a reference) and the joint multi-camera
// bundle adjustment (Ceres) over every camera's intrinsics and distortion, every camera's pose
// relative to camera 0 and every board pose, initialised through the visibility graph so cameras
// that never see the board together with camera 0 still calibrate through the others.
//
// RMS convention (OpenCV's calibrateCamera / stereoCalibrate): sqrt(sum ||observed - projected||^2
// / number of corner observations), in pixels.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

#include "calibration/cameras/board.h"
#include "camera/camera_model.h"
#include "common/progress.h"
#include "common/status.h"

namespace hc::calib {

// The board corners one camera found in one view. Views are numbered by the caller; the same
// number in two cameras means the same board pose (frames taken at the same moment).
struct ViewObservation {
  int view = 0;
  std::vector<int> ids;                 // BoardSpec::corner ids
  std::vector<Eigen::Vector2d> pixels;  // same length as ids
};

struct CameraObservations {
  std::string name;
  int width = 0;  // image size, px
  int height = 0;
  std::vector<ViewObservation> views;
};

enum class RobustLoss : std::uint8_t { kNone, kHuber, kCauchy };

struct CalibrationOptions {
  bool fix_aspect_ratio = false;  // fx = fy (OpenCV's CALIB_FIX_ASPECT_RATIO with ratio 1)
  bool fix_k3 = false;            // k3 = 0 (CALIB_FIX_K3)
  bool zero_tangential = false;   // p1 = p2 = 0 (CALIB_ZERO_TANGENT_DIST)
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale_px = 1.0;  // Huber / Cauchy scale
  // A view is flagged an outlier when its RMS exceeds this factor times the median view RMS.
  double outlier_factor = 3.0;
  int min_views_per_camera = 3;
  int min_points_per_view = 6;
  bool compute_std_devs = true;  // Ceres covariance (intrinsics and camera poses)
  int max_iterations = 200;
  int threads = 2;
  ProgressReporter* progress = nullptr;
};

struct ViewReport {
  std::string camera;
  int view = 0;
  int points = 0;
  double rms_px = 0.0;
  bool outlier = false;
};

struct CameraReport {
  std::string name;
  int views = 0;
  int points = 0;
  double rms_px = 0.0;
  // RMS of the single-camera OpenCV calibration that gave the initial guess (calibrate_rig runs
  // it on at most 10 of the camera's views and finds the other views' poses by solvePnP).
  double initial_rms_px = 0.0;
  // Standard deviations (empty when not computed): fx fy cx cy k1 k2 p1 p2 k3 (px and unitless;
  // 0 for fixed parameters) and the pose relative to camera 0 (rotation vector rad, t m; zeros
  // for camera 0, which defines the rig frame).
  std::vector<double> intrinsics_std;
  std::vector<double> pose_std;
  // Standard deviation of the camera centre (x, y, z in the rig frame, m), propagated from the
  // pose covariance (zeros for camera 0; empty when not computed).
  std::vector<double> center_std_m;
  std::string parent;  // the camera it was chained from in the visibility graph ("" for camera 0)
  int shared_views_with_parent = 0;
};

struct CalibrationSummary {
  RigCalibration rig;  // cameras in input order; camera 0 = identity pose
  std::vector<CameraReport> cameras;
  std::vector<ViewReport> views;  // every (camera, view)
  double joint_rms_px = 0.0;
  int observations = 0;  // corner observations
  int board_poses = 0;
  int iterations = 0;
  // Ceres stopped on a tolerance (function, gradient or parameter), not on the iteration limit
  // or a failure; termination is Ceres' message.
  bool converged = false;
  std::string termination;
  double initial_joint_rms_px = 0.0;
  double init_time_s = 0.0;
  double solve_time_s = 0.0;
  double covariance_time_s = 0.0;
  std::string covariance_note;  // why std devs are missing, when they are
  std::vector<ViewReport> outliers() const;
};

// OpenCV's calibrateCameraExtended on one camera (the reference single-camera calibration):
// model k1 k2 p1 p2 k3 with the option flags; std devs from OpenCV (intrinsics_std), per-view RMS.
Result<CalibrationSummary> calibrate_camera_opencv(const CameraObservations& camera,
                                                   const BoardSpec& board,
                                                   const CalibrationOptions& options = {});

// OpenCV's two-camera calibration (the peer program for a pair): calibrateCamera on each, then
// cv::stereoCalibrate over the views both saw (CALIB_USE_INTRINSIC_GUESS plus the option flags).
// Returns the summary with camera b's pose relative to a; joint_rms_px is stereoCalibrate's RMS.
Result<CalibrationSummary> stereo_calibrate_opencv(const CameraObservations& a,
                                                   const CameraObservations& b,
                                                   const BoardSpec& board,
                                                   const CalibrationOptions& options = {});

// The joint bundle adjustment over all cameras (one camera: a single-camera calibration refined by
// Ceres). kInvalidArgument when a camera has too few views or is not connected to camera 0
// through shared views.
Result<CalibrationSummary> calibrate_rig(const std::vector<CameraObservations>& cameras,
                                         const BoardSpec& board,
                                         const CalibrationOptions& options = {});

}  // namespace hc::calib
