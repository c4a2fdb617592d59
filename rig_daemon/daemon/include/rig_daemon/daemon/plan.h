// Capture plans: what one session does. A plan is a YAML file read through common/config.h, so
// every problem is reported as "FILE:LINE: key: expected ...". Two protocols (thesis 4.4, 5.6):
//
//   protocol: hand_held          # FSR probe held by a technician, cameras fired by the trigger
//   name: face_cheek
//   trigger: {rate_hz: 2, pulse_width_s: 0.001}
//   duration_s: 10
//   cameras: [cam0, cam1, cam2]
//
//   protocol: automated          # 4-DOF arm presses a probe with a 6-axis F/T sensor
//   name: tbp_block
//   locations:                   # probe tip positions (rig frame, m) and press directions
//     - {position_m: [0, 0, 0.062], direction: [0, 0, -1]}
//   force_levels_n: [20, 35]     # each location is pressed up to each level in `steps` steps
//   steps: 60                    # deformation steps per acquisition (30..200, thesis 5.6)
//   settle_s: 0.2
//   max_force_n: 45              # hard limit, also capped by the rig config
//   workspace: {min_m: [-0.1, -0.1, 0.0], max_m: [0.1, 0.1, 0.2]}
//   cameras: [cam0, cam1, cam2, cam3, cam4, cam5, cam6]
//
//   protocol: calibration        # a chessboard shown to the cameras in N poses, one trigger each
//   name: calib_board
//   board: {cols: 9, rows: 6, square_m: 0.006}   # inner corners, square size (+ margin_squares)
//   poses: 20                    # trigger pulses = board poses
//   seed: 3                      # simulated rigs: the seeded pose sequence (sim_scene.h)
//   dwell_s: 0.2                 # time per pose (a technician moves the board between pulses)
//   max_tilt_deg: 35             # optional, simulated pose sequence
//   cameras: [cam0, cam1, cam2]
//   trigger: {pulse_width_s: 0.001}              # optional
//   trigger_device: trigger      # optional (default: the rig's first trigger)
//
// On a simulated rig the calibration protocol shows the board in the world (the specimen and the
// probe are then not rendered) and the session gets a "sim_cameras" metadata record with the true
// camera parameters (rig_daemon/session/topics.h).
//
// All accept `specimen:` (a map of scalars recorded with the session) and `description:`.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/config.h"
#include "common/json.h"
#include "common/status.h"

namespace hc::rig {

// Thesis 5.6: "For each acquisition, we use 30 to 200 deformation steps".
inline constexpr int kMinSteps = 30;
inline constexpr int kMaxSteps = 200;
// No plan may ask for more than the F/T sensor's range (ATI Nano25: 125 N, thesis 5.6).
inline constexpr double kMaxPlanForceN = 125.0;

// An axis-aligned box in the rig frame (m).
struct WorkspaceBox {
  std::array<double, 3> min_m{-0.1, -0.1, 0.0};
  std::array<double, 3> max_m{0.1, 0.1, 0.2};
  Status read(ConfigNode node);
  Status validate() const;
  bool contains(const std::array<double, 3>& p_m) const;
  // The intersection of two boxes (may be empty: then min > max on some axis).
  WorkspaceBox intersect(const WorkspaceBox& other) const;
  bool empty() const;
  Json to_json() const;
};

struct TriggerSettings {
  double rate_hz = 2.0;
  double pulse_width_s = 0.001;
  Status read(ConfigNode node);
  Status validate() const;
};

struct HandHeldPlan {
  TriggerSettings trigger;
  double duration_s = 10.0;
  std::vector<std::string> cameras;  // device names from the rig config
  std::string fsr = "fsr";           // device name of the FSR
};

struct ProbeLocation {
  std::array<double, 3> position_m{};         // where the probe tip starts (just above contact)
  std::array<double, 3> direction{0, 0, -1};  // press direction, normalised on read
  Status read(ConfigNode node);
};

struct AutomatedPlan {
  std::vector<ProbeLocation> locations;
  std::vector<double> force_levels_n;
  int steps = 60;
  double settle_s = 0.2;
  double max_force_n = 45.0;
  double step_m = 0.0002;     // arm increment while seeking a step's target force
  double max_depth_m = 0.03;  // deepest press from the start position before giving up
  WorkspaceBox workspace;
  std::vector<std::string> cameras;
  std::string force_torque = "ft";
  std::string arm = "arm";
  std::string trigger_device = "trigger";
  TriggerSettings trigger;  // pulse width used for the per-step trigger
  int frames_per_step = 1;  // trigger pulses per step after settling
};

struct CalibrationPlan {
  int board_cols = 9;  // inner corners
  int board_rows = 6;
  double square_m = 0.006;
  double margin_squares = 1.0;
  int poses = 20;
  std::uint64_t seed = 1;
  double dwell_s = 0.2;
  double max_tilt_deg = 35.0;
  std::vector<std::string> cameras;
  TriggerSettings trigger;     // only pulse_width_s is used: one pulse per pose
  std::string trigger_device;  // empty: the rig's first trigger
};

enum class Protocol { kHandHeld, kAutomated, kCalibration };
std::string_view to_string(Protocol p);

struct Plan {
  std::string name = "session";
  std::string description;
  Protocol protocol = Protocol::kHandHeld;
  HandHeldPlan hand_held;
  AutomatedPlan automated;
  CalibrationPlan calibration;
  std::map<std::string, std::string> specimen;  // free-form metadata (scalars)
  std::string source_text;  // the YAML as read (recorded in the session metadata)

  Status read(ConfigNode node);
  // The plan as JSON (recorded as metadata and returned by `status --json`).
  Json to_json() const;
  // Number of trigger edges the plan will fire (hand-held: rate x duration; automated: locations
  // x levels x steps x frames_per_step; calibration: poses).
  std::int64_t expected_triggers() const;
};

// Parses a plan; `name` starts every message (the file name).
Result<Plan> parse_plan(std::string_view text, std::string_view name);
Result<Plan> load_plan(const std::filesystem::path& path);

}  // namespace hc::rig
