// The single-camera OpenCV calibration behind calibrate_camera_opencv and stereo_calibrate_opencv
// (calibrate.cpp), which also initialises calibrate_rig (calibrate_rig.cpp), and the small helpers
// both files use. Not a public header: the public interface is calibrate.h.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "calibration/cameras/calibrate.h"
#include "common/clock.h"

namespace hc::calib {

constexpr int kIntrinsics = 9;  // fx fy cx cy k1 k2 p1 p2 k3

double median(std::vector<double> v);

struct OpenCvCalibration {
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, per_view_errors;
  double rms = 0.0;
  std::vector<int> views;  // view number of each rvec
  std::vector<int> points;
};

// max_views > 0: calibrateCamera on at most that many views spread through the list, then every
// view's pose by solvePnP with those intrinsics (an initial guess for the bundle adjustment:
// calibrateCamera's dense Levenberg-Marquardt over 9 + 6 N parameters took 17 s for 7 cameras x
// ~45 views, 20 views plus solvePnP 3.2 s; 10 views halved bench_calibration's initialisation
// again). The joint solve refines everything: the synthetic rig tests reach the same optimum
// (identical errors and iteration counts) from either start.
Result<OpenCvCalibration> run_opencv(const CameraObservations& cam, const BoardSpec& board,
                                     const CalibrationOptions& options, int max_views = 0);

CameraModel model_from(const std::string& name, int w, int h, const double* intr, bool fix_aspect);

}  // namespace hc::calib
