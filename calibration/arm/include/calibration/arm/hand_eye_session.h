// Hand-eye observations from a recorded session (`hardcopy calib hand-eye`): for every step
// (/session/steps, else every /session/sync record) the arm's measured pose (the last /<arm>/state
// at or before the step's trigger edge), and the probe's two shaft markers triangulated in the rig
// frame from the step's camera frames (processing/markers detect_blobs + processing/tracking
// match_views over the calibration's cameras).
//
// Which triangulated points are the shaft markers: the specimen's dots form a dense grid (3 mm
// spacing) while the shaft markers sit 50 mm apart and >= 50 mm above the surface, so the shaft
// markers are the points with no other point within `isolation_m`. A step with exactly two such
// points contributes them; marker 0 (nearer the tip) is the one nearer the centroid of the
// specimen's dots; with no specimen dots the pairs are labelled consistently along the first
// pair's direction and, after a solve, swapped if marker 1 turned out lower along tool z (the
// solution's rotation does not depend on the labels).
//
// The shaft is vertical on a 4-DOF arm, so the markers lie (up to a bent shaft) on the yaw axis:
// their tool-z (distance from the tip along the shaft) must be known for marker 0 (see
// hand_eye.h); it comes from `marker0_tool_z_m` (default: the simulator's probe, 0.06 m).
//
// On simulated sessions /sim/ground_truth carries shaft_markers_m (world) per trigger index; the
// error of X p_ij against them is reported, and the metadata "sim_cameras" gives the true pose of
// the first calibrated camera, i.e. the true world_from_rig.
//
// An arm that never turns (the automated plans press at yaw 0) leaves the marker offsets
// unobservable; marker 0 is then held on the shaft axis at (0, 0, marker0_tool_z_m).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calibration/arm/hand_eye.h"
#include "camera/camera_model.h"
#include "common/status.h"

namespace hc::calib {

struct HandEyeSessionOptions {
  std::string arm_device;          // "" = the first arm channel
  double marker0_tool_z_m = 0.06;  // ProbeLook::marker_distances_m[0] of the simulator
  double isolation_m = 0.02;
  std::size_t max_steps = 0;  // 0: all
  // Shaft-marker detection (processing/markers detect_blobs): the markers are bright balls on a
  // grey shaft, so a local-mean threshold this many grey levels above the surroundings separates
  // them from the shaft (Otsu would take the shaft too), and the area floor drops the specimen's
  // much smaller dots.
  double marker_local_offset = 60.0;
  int marker_local_block_px = 31;
  double min_marker_area_px = 8.0;
  HandEyeOptions solver;  // marker0_tool_z_m is set from the field above
};

struct HandEyeSessionData {
  HandEyeProblem problem;
  std::size_t steps = 0;       // steps in the session
  std::size_t steps_used = 0;  // steps with an arm pose and exactly two shaft markers
  // Per observation: the simulator's true world position of that shaft marker (when present).
  std::vector<std::optional<Eigen::Vector3d>> truth_world_m;
  bool markers_ordered_by_specimen = false;  // marker 0 chosen by the specimen's dots
  // The true world_from_rig of a simulated rig (metadata "sim_cameras": the pose of the
  // calibration's first camera), when the session has it.
  std::optional<Eigen::Isometry3d> truth_world_from_rig;
};

// kInvalidArgument: unreadable session, no arm state channel, camera/calibration mismatch (see
// tracking::read_session_detections).
Result<HandEyeSessionData> read_hand_eye_session(const std::filesystem::path& session,
                                                 const RigCalibration& calibration,
                                                 const HandEyeSessionOptions& options);

struct HandEyeSessionResult {
  HandEyeResult solution;
  std::size_t steps = 0, steps_used = 0;
  bool has_truth = false;
  double truth_rms_m = 0.0;  // |X p_ij - truth| over the observations with truth
  double truth_max_m = 0.0;
  bool has_truth_transform = false;  // sim_cameras present
  double truth_translation_error_m = 0.0;
  double truth_rotation_error_deg = 0.0;
  Json to_json() const;
};

// Reads, solves (re-labelling once when the specimen did not decide the order) and compares with
// the truth. kFailedPrecondition from the solver (too few steps, unobservable poses).
Result<HandEyeSessionResult> calibrate_hand_eye_from_session(const std::filesystem::path& session,
                                                             const RigCalibration& calibration,
                                                             const HandEyeSessionOptions& options);

}  // namespace hc::calib
