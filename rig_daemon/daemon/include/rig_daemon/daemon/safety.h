// The daemon's own safety checks (the arm's limits are not trusted alone): the workspace box and
// max force of the plan and the rig config (the stricter of each applies), a stalled force stream,
// and estop. The scheduler calls these once per control cycle and stops the arm in the same cycle
// when one trips, so the delay from the crossing sample to the stop command is at most one cycle
// (measured and recorded: SafetyTrip::latency_ns).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/devices/types.h"

namespace hc::rig {

struct SafetyLimits {
  WorkspaceBox workspace;     // the intersection of the rig's and the plan's boxes
  double max_force_n = 50.0;  // the smaller of the rig's and the plan's
  std::int64_t stall_timeout_ns = 50'000'000;
};

// The limits in force for `plan` on a rig with `rig_box` / `rig_max_force_n`. kInvalidArgument
// when the boxes do not overlap.
Result<SafetyLimits> combine_limits(const WorkspaceBox& rig_box, double rig_max_force_n,
                                    double stall_timeout_s, const WorkspaceBox* plan_box,
                                    const double* plan_max_force_n);

struct SafetyTrip {
  enum class Kind {
    kOverForce,
    kStalledForce,
    kWorkspace,
    kEstop,
    kDeviceError,
    kStartCheck,  // refused to start: force above start_max_force_n, or the arm in fault
  };
  Kind kind = Kind::kOverForce;
  std::string message;
  std::int64_t sample_host_ns = 0;  // the sample that crossed the limit (over-force)
  std::int64_t detected_ns = 0;     // when the daemon saw it
  std::int64_t stop_sent_ns = 0;    // when Arm::stop() returned
  double force_n = 0.0;
  std::int64_t latency_ns() const { return stop_sent_ns - sample_host_ns; }
  Json to_json() const;
};
std::string_view to_string(SafetyTrip::Kind kind);

class SafetyMonitor {
 public:
  explicit SafetyMonitor(SafetyLimits limits) : limits_(limits) {}
  const SafetyLimits& limits() const { return limits_; }

  // Magnitude of the force vector against max_force_n; returns a trip for the first sample over.
  std::optional<SafetyTrip> check_wrench(const devices::WrenchSample& sample, std::int64_t now_ns);
  // A stalled stream: while `armed` (the arm may be in contact or moving), no F/T sample for more
  // than stall_timeout_ns. `last_sample_ns` < 0: none yet (counted from `armed_since_ns`).
  std::optional<SafetyTrip> check_stall(bool armed, std::int64_t last_sample_ns,
                                        std::int64_t armed_since_ns, std::int64_t now_ns) const;
  // OK when the pose is inside the workspace box; kInvalidArgument naming the axis otherwise.
  Status check_target(const devices::ArmPose& pose) const;

 private:
  SafetyLimits limits_;
};

}  // namespace hc::rig
