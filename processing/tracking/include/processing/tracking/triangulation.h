// Multi-view triangulation of one point over calibrated cameras (hc::CameraModel):
// a linear DLT on undistorted normalised image coordinates (Hartley & Zisserman, "Multiple View
// Geometry", 2nd ed., Sec. 12.2, each view's rows scaled so every camera counts alike), then a
// Gauss-Newton / Levenberg-Marquardt refinement minimising the reprojection error in pixels through
// the full distortion model (H&Z Sec. 12.3's "gold standard" cost for n views).
//
// Frames: the point is in the rig frame of the cameras (x_cam = R x_rig + t), metres; pixels
// follow OpenCV ((0, 0) at the centre of the top-left pixel).
#pragma once

#include <Eigen/Core>

#include <vector>

#include "camera/camera_model.h"
#include "common/status.h"

namespace hc::tracking {

// One image observation of the point: the camera (must outlive the call) and the distorted pixel.
struct View {
  const CameraModel* camera = nullptr;
  Eigen::Vector2d pixel_px = Eigen::Vector2d::Zero();
};

struct TriangulationOptions {
  bool refine = true;               // non-linear refinement after the DLT
  int max_iterations = 20;          // of the refinement
  double step_tolerance_m = 1e-10;  // stop when an update moves the point less than this

  Status validate() const;
};

struct Triangulation {
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero();  // rig frame
  double rms_px = 0.0;              // reprojection RMS over the views (per-view distance)
  std::vector<double> residual_px;  // per view: |project(point) - pixel|
  int iterations = 0;               // refinement iterations taken
  bool converged = false;           // refinement met the step tolerance (true when !refine)
  // Largest angle (rad) between any two viewing rays; a tiny angle means a poorly conditioned
  // depth.
  double max_ray_angle_rad = 0.0;
};

// Linear DLT only (no refinement). Needs >= 2 views with non-null, valid cameras.
// kInvalidArgument on fewer views or null cameras; kFailedPrecondition when the point is behind a
// camera or the system is degenerate (parallel rays / coincident centres).
Result<Eigen::Vector3d> triangulate_linear(const std::vector<View>& views);

// DLT + refinement; the returned residuals are those of the final point.
Result<Triangulation> triangulate(const std::vector<View>& views,
                                  const TriangulationOptions& options = {});

// Reprojection distance (px) of a rig-frame point in one view; +infinity when it is behind the
// camera.
double reprojection_error_px(const View& view, const Eigen::Vector3d& point_m);

}  // namespace hc::tracking
