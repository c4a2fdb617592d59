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
// specimen's dots, or, with no specimen dots, the labelling is fixed by the solver trying both
// orders and keeping the lower residual.
//
// The shaft is vertical on a 4-DOF arm, so the markers lie (up to a bent shaft) on the yaw axis:
// their tool-z (distance from the tip along the shaft) must be known for marker 0 (see
// hand_eye.h); it comes from `marker0_tool_z_m` (default: the simulator's probe, 0.06 m).
//
// On simulated sessions /sim/ground_truth carries shaft_markers_m (world) per trigger index; the
// error of X p_ij against them is reported.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calibration/arm/hand_eye.h"
#include "calibration/cameras/camera_model.h"
#include "common/status.h"

namespace hc::calib {

struct HandEyeSessionOptions {
  std::string arm_device;          // "" = the first arm channel
  double marker0_tool_z_m = 0.06;  // ProbeLook::marker_distances_m[0] of the simulator
  double isolation_m = 0.02;
  std::size_t max_steps = 0;  // 0: all
  HandEyeOptions solver;      // marker0_tool_z_m is set from the field above
};

struct HandEyeSessionData {
  HandEyeProblem problem;
  std::size_t steps = 0;       // steps in the session
  std::size_t steps_used = 0;  // steps with an arm pose and exactly two shaft markers
  // Per observation: the simulator's true world position of that shaft marker (when present).
  std::vector<std::optional<Eigen::Vector3d>> truth_world_m;
  bool markers_ordered_by_specimen = false;  // marker 0 chosen by the specimen's dots
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
  Json to_json() const;
};

// Reads, solves (both marker orders when the specimen did not decide it) and compares with the
// truth. kFailedPrecondition from the solver (too few steps, unobservable poses).
Result<HandEyeSessionResult> calibrate_hand_eye_from_session(const std::filesystem::path& session,
                                                             const RigCalibration& calibration,
                                                             const HandEyeSessionOptions& options);

}  // namespace hc::calib
