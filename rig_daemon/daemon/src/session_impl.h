// Private to the scheduler's translation units (scheduler.cpp: the session's API, finish;
// scheduler_setup.cpp: devices, channel table, metadata; scheduler_cycle.cpp: the control cycle;
// scheduler_protocols.cpp: the plan modes; session_safety.cpp: trips, start checks, the retract
// after a safety stop).
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "rig_daemon/daemon/scheduler.h"
#include "rig_daemon/recording/mcap_records.h"
#include "rig_daemon/daemon/session_source.h"

namespace hc::rig {

namespace rec = hc::recording;
namespace dev = hc::devices;

// Below this force magnitude the probe is taken to be out of contact (the sim F/T noise is a few
// hundredths of a newton; ATI Nano25 resolution is 1/24 N, thesis 5.6).
inline constexpr double kContactForceN = 0.2;
// A step is reached when the force is within this fraction of the level below its target.
inline constexpr double kStepTolerance = 0.02;
// Probe increments while seeking a step's force stay within [step_m / 20, 5 step_m].
inline constexpr int kMaxSeekMovesPerStep = 40;
inline constexpr double kApproachSpeedMps = 0.05;
inline constexpr double kPressSpeedMps = 0.02;
// How long to wait for the frames and samples of one trigger edge.
inline constexpr std::int64_t kEdgeTimeoutNs = 2'000'000'000;
// How long to wait for a fresh F/T sample after an arm move. A stalled stream trips the safety
// check (stall_timeout_s) in the same loop first; this only bounds the wait when the control
// loop itself is slow (e.g. a heavily loaded machine), which is not a gap in the F/T stream.
inline constexpr std::int64_t kFtAfterMoveTimeoutNs = 1'000'000'000;
// Progress events at most this often.
inline constexpr std::int64_t kProgressPeriodNs = 100'000'000;

inline double norm3(const std::array<double, 3>& v) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

// Samples averaged for the "current force" (about 1.4 ms of a 7 kHz stream).
inline constexpr std::size_t kForceWindow = 10;

// A number for a message: "80", "0.0612", "12.5" (not std::to_string's "80.000000").
inline std::string num(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

using rec::to_bytes;

inline Json pose_json(const dev::ArmPose& p) {
  return Json{{"x_m", p.x_m}, {"y_m", p.y_m}, {"z_m", p.z_m}, {"yaw_rad", p.yaw_rad}};
}

struct Session::Impl {
  Impl(Session& s, Rig& r, SessionOptions o) : self(s), rig(r), opts(std::move(o)) {}

  Session& self;
  Rig& rig;
  SessionOptions opts;
  dev::Clock& clock() { return rig.clock(); }

  // Devices of this session.
  dev::Trigger* trigger = nullptr;
  std::vector<dev::Camera*> cameras;
  dev::ForceTorque* ft = nullptr;
  dev::Fsr* fsr = nullptr;
  dev::Arm* arm = nullptr;
  std::vector<dev::Device*> used;

  std::unique_ptr<Recorder> recorder;
  std::unique_ptr<Associator> assoc;
  std::unique_ptr<SafetyMonitor> safety;

  // Channels.
  std::uint16_t ch_edges = 0, ch_ft = 0, ch_fsr = 0, ch_arm_state = 0, ch_arm_cmd = 0;
  std::vector<std::uint16_t> ch_cams;
  std::uint16_t ch_sync = 0, ch_steps = 0, ch_events = 0;
  // Records besides the devices' (a simulated rig's ground truth); null when there are none.
  std::unique_ptr<SessionSource> source;
  std::set<std::string> session_cameras;  // names

  // Control flags (any thread).
  std::atomic<bool> stop_requested{false};
  std::atomic<bool> pause_requested{false};
  std::atomic<bool> estop_requested{false};
  std::atomic<std::int64_t> estop_stop_ns{-1};  // when Session::estop() stopped the arm

  // Loop state (session thread).
  std::int64_t next_cycle_ns = 0;
  std::int64_t period_ns = 1'000'000;
  std::int64_t last_ft_ns = -1;
  std::int64_t armed_since_ns = -1;  // stall checks run while >= 0
  std::deque<double> recent_force;
  std::uint64_t edges_received = 0;
  std::optional<std::uint64_t> last_edge_index;
  std::uint64_t arm_command_sequence = 0;
  std::optional<dev::ArmState> last_arm;
  std::optional<SafetyTrip> trip;
  // Automated: where the current press started (clear of the specimen), the pose a safety stop
  // retracts to; and what the retract did (summary "retract").
  std::optional<dev::ArmPose> safe_pose;
  Json retract = nullptr;
  std::string end_reason;
  std::int64_t last_progress_ns = 0;
  std::int64_t start_ns = 0;
  std::int64_t max_cycle_gap_ns = 0;
  std::int64_t last_cycle_ns = -1;

  // Scratch buffers.
  std::vector<dev::TriggerEdge> edges_buf;
  std::vector<dev::Frame> frames_buf;
  std::vector<dev::WrenchSample> ft_buf;
  std::vector<dev::FsrSample> fsr_buf;
  rec::Bytes image_buf;

  // Progress (guarded).
  mutable std::mutex progress_mutex;
  Json progress_json = Json::object();
  std::int64_t done = 0;
  std::int64_t total = 0;
  std::string step_text;

  // ---------------------------------------------------------------------------------------------
  // setup(): choose_devices(), open_recording() (the channel table), write_opening_metadata(),
  // then the ground-truth stream and the devices started.
  Status setup();
  Status choose_devices();
  Status open_recording();
  Status write_opening_metadata();
  Status poll();
  Status cycle();
  Status wait_for(const std::function<bool()>& done_pred, std::int64_t timeout_ns,
                  std::string_view what);
  Status pause_point();
  void record_event(std::string_view kind, const std::string& message);
  void handle_trip(SafetyTrip t);
  // session_safety.cpp: the stop command and the arm's state after it on the arm's channels.
  void record_arm_stop(std::int64_t stop_ns);
  // Before anything moves (automated): the arm not in fault, the force below start_max_force_n.
  Status check_start_conditions();
  // After an over-force or workspace stop: back along the press to safe_pose, watching the force.
  void retract_after_trip();
  Status retract_to(const dev::ArmPose& pose);
  void update_progress(bool force_event);
  Status run_hand_held();
  Status run_replay();
  Status run_automated();
  Status run_calibration();
  Status move_to(const dev::ArmPose& pose, double speed);
  Status fire_and_collect(std::vector<std::uint64_t>& indices, int pulses);
  double current_force() const;
  void record_arm_state(const dev::ArmState& s);
  Json finish(Status run_status);
};

}  // namespace hc::rig
