// Marker correspondences across calibrated views and tracking through deformation steps
// (thesis Sec. 4.4.2, 5.6), rigid registration (Horn's absolute orientation) and the filling of
// occluded markers by a smooth deformation.
//
// All 3-D points are in the rig frame of the cameras (metres) unless a function says otherwise;
// detections are distorted pixels as detect_blobs returns them.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

#include "camera/camera_model.h"
#include "common/status.h"

namespace hc::tracking {

// Detections of one instant: [camera][k] pixel, cameras in the order of the camera list.
using FrameDetections = std::vector<std::vector<Eigen::Vector2d>>;

struct MatchOptions {
  // Epipolar distance (px, in the second image of a pair, on undistorted coordinates) for a
  // candidate pair.
  double epipolar_tolerance_px = 1.5;
  // A hypothesis' projection must land this close to a detection for that camera to support it.
  double support_tolerance_px = 1.5;
  // Views a marker needs at initialisation: 3 by default (the 3-view consistency that rejects the
  // ambiguous pairs a regular grid produces along epipolar lines).
  int min_views = 3;
  double max_rms_px = 1.0;  // reprojection RMS of an accepted marker (after refinement)

  Status validate() const;
};

// A reconstructed marker: rig-frame point and, per camera, the detection index used (-1: none).
struct MatchedPoint {
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero();
  std::vector<int> detection;
  double rms_px = 0;
  int views() const;
};

// Initial correspondences without a prior (the first, undeformed step): every pair of cameras
// proposes candidates by the epipolar constraint (essential matrices from the calibration, on
// undistorted normalised coordinates), each candidate is triangulated and scored by how many
// other cameras see a detection at its projection; candidates are accepted greedily (most views,
// then lowest RMS) with every detection used at most once, then refined over all their views.
// kInvalidArgument when the detection list does not match the cameras.
Result<std::vector<MatchedPoint>> match_views(const std::vector<CameraModel>& cameras,
                                              const FrameDetections& detections,
                                              const MatchOptions& options = {});

struct TrackOptions {
  MatchOptions match;             // for the initial step
  double search_radius_px = 8.0;  // around a predicted projection
  int min_views = 2;              // a marker seen by fewer cameras in a step is not measured
  double max_rms_px = 1.0;        // worse: drop the worst view and retry, else not measured
  // Ratio test: the nearest detection must be this much closer than the second nearest
  // (ambiguous assignments are dropped, not guessed).
  double ambiguity_ratio = 0.6;
  // Markers hidden in the first step (e.g. by the probe) appear later: detections left over after
  // the association are matched like the first step's (match_views) and become new markers when
  // they are this far from every known marker.
  bool detect_new_markers = true;
  double new_marker_separation_m = 1.0e-3;
  // A marker found after the first step that goes unmeasured this many steps in a row is retired
  // (not predicted any more): e.g. the probe's own markers, which leave with the probe.
  int retire_after_steps = 2;

  Status validate() const;
};

// Per-marker vectors have one entry per marker known after the step (markers found in it included).
struct StepResult {
  std::vector<Eigen::Vector3d> points_m;  // per marker (last known / predicted when not measured)
  std::vector<std::uint8_t> measured;     // per marker: 1 when triangulated in this step
  std::vector<int> views;                 // per marker: cameras used
  std::vector<std::vector<int>> owner;    // [camera][detection] -> marker or -1
  double reprojection_rms_px = 0;         // over all measured markers' views
  std::size_t detections = 0;             // in all cameras
  std::size_t matched_detections = 0;     // assigned to a measured marker
};

// Tracks markers through steps: initialise() finds them (match_views), track() associates each
// later step's detections by projecting the prediction (previous position plus the previous
// step's displacement) into every camera, taking the nearest unambiguous detection within the
// search radius, triangulating (DLT + refinement) and rejecting outlier views. When fewer than 95 %
// are found it also tries the previous positions and the first-seen positions (the probe let go),
// then re-predicts unmeasured markers from their measured neighbours' displacement and associates
// again while that finds more. Leftover detections become new markers (see TrackOptions).
class MarkerTracker {
 public:
  MarkerTracker(std::vector<CameraModel> cameras, TrackOptions options);
  // Finds the markers in the first step; returns its StepResult (every marker measured).
  Result<StepResult> initialise(const FrameDetections& detections);
  // Associates and triangulates a later step.
  Result<StepResult> track(const FrameDetections& detections);
  std::size_t num_markers() const { return position_.size(); }
  // Step (0-based count of initialise/track calls) in which each marker was found.
  const std::vector<int>& birth_step() const { return birth_; }
  const std::vector<CameraModel>& cameras() const { return cameras_; }

 private:
  // Markers from the step's leftover detections, matched among themselves, away from the known
  // ones: appended to the tracker and to *best.
  void add_new_markers(const FrameDetections& detections, StepResult* best);

  std::vector<CameraModel> cameras_;
  TrackOptions options_;
  std::vector<Eigen::Vector3d> position_;  // last measured (or predicted) position
  std::vector<Eigen::Vector3d> velocity_;  // last step's displacement
  std::vector<Eigen::Vector3d> rest_;      // where each marker was first seen
  std::vector<int> birth_;
  std::vector<int> unmeasured_run_;
  std::vector<std::uint8_t> retired_;
  int step_ = 0;
  bool initialised_ = false;
};

// Horn's absolute orientation (closed form; Eigen::umeyama, which solves the same least-squares
// problem by SVD): the rigid T minimising sum |T src_i - dst_i|^2. #P by 3 each, P >= 3 not
// collinear, else kFailedPrecondition.
Result<Eigen::Isometry3d> absolute_orientation(const Eigen::Matrix3Xd& src,
                                               const Eigen::Matrix3Xd& dst);

struct IcpResult {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // target_from_source
  std::vector<int> match;  // per source point: target index or -1 (farther than max_distance)
  double rms_m = 0;        // over matched pairs
  int iterations = 0;
};
// Rigid ICP of `source` onto `target` from `initial`: nearest target point per source point,
// pairs beyond max_distance_m dropped, Horn's closed form on the rest, until the matches stop
// changing. Each target point is matched at most once (the nearer source wins).
Result<IcpResult> icp(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target, const Eigen::Isometry3d& initial,
                      double max_distance_m, int max_iterations = 30);

// Smooth interpolation of displacements (the occlusion filling of Sec. 4.4.2): a 3-D biharmonic
// radial basis function (kernel |r|, plus an affine part) through the known displacements, with a
// small smoothing term `regularization_m` (0: interpolating). `known_points` #K, `known_disp` #K,
// `query` #Q. Needs K >= 4 non-coplanar points for the affine part; with fewer the mean
// displacement is used.
std::vector<Eigen::Vector3d> interpolate_displacements(
    const std::vector<Eigen::Vector3d>& known_points,
    const std::vector<Eigen::Vector3d>& known_disp, const std::vector<Eigen::Vector3d>& query,
    double regularization_m = 0.0);

}  // namespace hc::tracking
