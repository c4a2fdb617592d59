// libFuzzer target for the plan and rig-config readers: arbitrary bytes are read as a capture plan
// and as a rig config. Errors are the expected outcome; a plan that reads must satisfy every
// documented bound (crashes, hangs, leaks and sanitizer reports are bugs).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"

namespace {

void check(const hc::rig::Plan& plan) {
  using hc::rig::Protocol;
  if (plan.protocol == Protocol::kAutomated) {
    const hc::rig::AutomatedPlan& p = plan.automated;
    if (p.steps < hc::rig::kMinSteps || p.steps > hc::rig::kMaxSteps) __builtin_trap();
    if (p.locations.empty() || p.force_levels_n.empty()) __builtin_trap();
    if (!(p.max_force_n > 0 && p.max_force_n <= hc::rig::kMaxPlanForceN)) __builtin_trap();
    for (double f : p.force_levels_n)
      if (!(f > 0 && f <= p.max_force_n)) __builtin_trap();
    for (const hc::rig::ProbeLocation& l : p.locations) {
      if (!p.workspace.contains(l.position_m)) __builtin_trap();
      const double n = std::hypot(l.direction[0], l.direction[1], l.direction[2]);
      if (!(std::abs(n - 1.0) < 1e-9)) __builtin_trap();
    }
  } else if (plan.protocol == Protocol::kCalibration) {
    const hc::rig::CalibrationPlan& p = plan.calibration;
    if (p.board_cols < 2 || p.board_cols > 64 || p.board_rows < 2 || p.board_rows > 64)
      __builtin_trap();
    if (!(p.square_m > 0 && p.square_m <= 1.0)) __builtin_trap();
    if (p.poses < 1 || p.poses > 1000) __builtin_trap();
    if (!(p.dwell_s >= 0 && p.dwell_s <= 60) || !(p.max_tilt_deg >= 0 && p.max_tilt_deg <= 80))
      __builtin_trap();
    if (plan.expected_triggers() != p.poses) __builtin_trap();
  } else {
    const hc::rig::HandHeldPlan& p = plan.hand_held;
    if (!(p.trigger.rate_hz > 0) || !(p.trigger.pulse_width_s < 1.0 / p.trigger.rate_hz))
      __builtin_trap();
    if (!(p.duration_s > 0)) __builtin_trap();
  }
  (void)plan.to_json().dump();
  (void)plan.expected_triggers();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (hc::Result<hc::rig::Plan> plan = hc::rig::parse_plan(text, "fuzz.yaml"); plan.ok())
    check(*plan);
  if (hc::Result<hc::rig::RigConfig> rig = hc::rig::parse_rig_config(text, "fuzz.yaml"); rig.ok()) {
    if (rig->devices.empty() || rig->workspace.empty()) __builtin_trap();
    (void)rig->to_json().dump();
  }
  return 0;
}
