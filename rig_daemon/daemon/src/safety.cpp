#include "rig_daemon/daemon/safety.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace hc::rig {

Result<SafetyLimits> combine_limits(const WorkspaceBox& rig_box, double rig_max_force_n,
                                    double stall_timeout_s, const WorkspaceBox* plan_box,
                                    const double* plan_max_force_n) {
  SafetyLimits l;
  l.workspace = plan_box ? rig_box.intersect(*plan_box) : rig_box;
  if (l.workspace.empty())
    return invalid_argument("the plan's workspace box does not overlap the rig's");
  l.max_force_n = plan_max_force_n ? std::min(rig_max_force_n, *plan_max_force_n) : rig_max_force_n;
  l.stall_timeout_ns = static_cast<std::int64_t>(std::llround(stall_timeout_s * 1e9));
  return l;
}

std::string_view to_string(SafetyTrip::Kind kind) {
  switch (kind) {
    case SafetyTrip::Kind::kOverForce:
      return "over_force";
    case SafetyTrip::Kind::kStalledForce:
      return "stalled_force_stream";
    case SafetyTrip::Kind::kWorkspace:
      return "workspace";
    case SafetyTrip::Kind::kEstop:
      return "estop";
    case SafetyTrip::Kind::kDeviceError:
      return "device_error";
    case SafetyTrip::Kind::kStartCheck:
      return "start_check";
  }
  return "unknown";
}

Json SafetyTrip::to_json() const {
  Json j{{"kind", to_string(kind)},
         {"message", message},
         {"detected_ns", detected_ns},
         {"stop_sent_ns", stop_sent_ns}};
  if (kind == Kind::kOverForce) {
    j["sample_host_ns"] = sample_host_ns;
    j["force_n"] = force_n;
    j["latency_ns"] = latency_ns();
  }
  return j;
}

std::optional<SafetyTrip> SafetyMonitor::check_wrench(const devices::WrenchSample& s,
                                                      std::int64_t now_ns) {
  const double f = std::sqrt(s.force_n[0] * s.force_n[0] + s.force_n[1] * s.force_n[1] +
                             s.force_n[2] * s.force_n[2]);
  // NaN from a broken sensor is treated as over the limit.
  if (f <= limits_.max_force_n) return std::nullopt;
  SafetyTrip t;
  t.kind = SafetyTrip::Kind::kOverForce;
  t.sample_host_ns = s.host_ns;
  t.detected_ns = now_ns;
  t.force_n = f;
  std::ostringstream m;
  m << "force " << f << " N over the limit of " << limits_.max_force_n << " N (F/T sample "
    << s.sequence << ")";
  t.message = m.str();
  return t;
}

std::optional<SafetyTrip> SafetyMonitor::check_stall(bool armed, std::int64_t last_sample_ns,
                                                     std::int64_t armed_since_ns,
                                                     std::int64_t now_ns) const {
  if (!armed) return std::nullopt;
  const std::int64_t since = std::max(last_sample_ns, armed_since_ns);
  if (now_ns - since <= limits_.stall_timeout_ns) return std::nullopt;
  SafetyTrip t;
  t.kind = SafetyTrip::Kind::kStalledForce;
  t.detected_ns = now_ns;
  t.sample_host_ns = since;
  std::ostringstream m;
  m << "no force-torque sample for " << double(now_ns - since) * 1e-6 << " ms (limit "
    << double(limits_.stall_timeout_ns) * 1e-6 << " ms)";
  t.message = m.str();
  return t;
}

Status SafetyMonitor::check_target(const devices::ArmPose& p) const {
  const std::array<double, 3> v{p.x_m, p.y_m, p.z_m};
  constexpr const char* kAxis[] = {"x", "y", "z"};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!(v[i] >= limits_.workspace.min_m[i] && v[i] <= limits_.workspace.max_m[i])) {
      std::ostringstream m;
      m << "arm target " << kAxis[i] << " = " << v[i] << " m is outside the workspace ["
        << limits_.workspace.min_m[i] << ", " << limits_.workspace.max_m[i] << "] m";
      return invalid_argument(m.str());
    }
  }
  return {};
}

}  // namespace hc::rig
