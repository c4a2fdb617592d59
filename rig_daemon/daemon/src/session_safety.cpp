// The session's side of a safety stop: the trip itself (arm stopped in the same cycle, trigger
// halted), the record of what the arm was told and did (the stop on the arm's command channel,
// its state after it), the checks before an automated capture moves anything, and the retract
// to the press's start pose after an over-force or workspace stop.
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "session_impl.h"

namespace hc::rig {

namespace {

// Retract speed after a safety stop: slow (a third of the press speed elsewhere), the force is
// watched all the way.
constexpr double kRetractSpeedMps = 0.01;
// While retracting, the force may not rise this far above the force at the stop.
constexpr double kRetractForceRiseN = 2.0;
// How long the start check waits for a window of F/T samples.
constexpr std::int64_t kStartCheckTimeoutNs = 1'000'000'000;

}  // namespace

void Session::Impl::record_arm_stop(std::int64_t stop_ns) {
  if (arm == nullptr || recorder == nullptr) return;
  dev::ArmCommand stop;
  stop.type = dev::ArmCommand::Type::kStop;
  stop.sequence = ++arm_command_sequence;
  recorder->write(ch_arm_cmd, stop_ns, stop_ns, static_cast<std::uint32_t>(stop.sequence),
                  to_bytes(session::to_json(stop)));
  if (arm->state() != dev::DeviceState::kActive) return;
  // The arm's own account of the stop (kStopped, or kFault when it is the arm that failed).
  if (Result<dev::ArmState> st = arm->read(); st.ok()) record_arm_state(*st);
}

void Session::Impl::handle_trip(SafetyTrip t) {
  if (trip) return;  // the first trip is the one that counts
  if (arm != nullptr) (void)arm->stop();
  t.stop_sent_ns = clock().now_ns();
  if (trigger != nullptr && trigger->state() == dev::DeviceState::kActive) (void)trigger->stop();
  trip = t;
  // An estop stopped the arm from the control thread already; its command carries that time.
  const std::int64_t early = estop_stop_ns.load();
  record_arm_stop(t.kind == SafetyTrip::Kind::kEstop && early >= 0 ? early : t.stop_sent_ns);
  const std::int64_t now = t.stop_sent_ns;
  session::EventRecord event;
  event.host_ns = now;
  event.kind = to_string(t.kind);
  event.message = t.message;
  event.detected_ns = t.detected_ns;
  event.stop_sent_ns = t.stop_sent_ns;
  if (t.kind == SafetyTrip::Kind::kOverForce) {
    event.sample_host_ns = t.sample_host_ns;
    event.force_n = t.force_n;
    event.latency_ns = t.latency_ns();
  }
  recorder->write(ch_events, now, now, 0, to_bytes(session::to_json(event)));
  if (opts.on_event) {
    Json j = t.to_json();
    j["host_ns"] = now;
    opts.on_event("safety", j);
  }
}

Status Session::Impl::check_start_conditions() {
  const auto refuse = [&](const std::string& message) {
    SafetyTrip t;
    t.kind = SafetyTrip::Kind::kStartCheck;
    t.message = message;
    t.detected_ns = clock().now_ns();
    t.sample_host_ns = t.detected_ns;
    t.force_n = current_force();
    handle_trip(t);
    return Status(StatusCode::kCancelled, message);
  };
  HC_ASSIGN_OR_RETURN(dev::ArmState st, arm->read());
  record_arm_state(st);
  if (st.motion == dev::ArmMotion::kFault)
    return refuse("arm '" + arm->name() + "' is in fault (code " + std::to_string(st.fault_code) +
                  ": " + st.fault + "); clear it with `rigctl reset` before starting");
  // The force before anything moves (still relative to the last tare): a probe left pressing the
  // specimen must not be tared away and then driven into it again.
  const std::int64_t since = clock().now_ns();
  armed_since_ns = since;
  recent_force.clear();
  HC_RETURN_IF_ERROR(
      wait_for([&] { return last_ft_ns >= since && recent_force.size() >= kForceWindow; },
               kStartCheckTimeoutNs, "the force before the start"));
  const double limit = rig.config().start_max_force_n;
  if (current_force() > limit)
    return refuse("force " + num(current_force()) +
                  " N before the start, above start_max_force_n " + num(limit) +
                  " N: the probe may be pressing the specimen; move it clear, then " +
                  "`rigctl reset`");
  return {};
}

Status Session::Impl::retract_to(const dev::ArmPose& pose) {
  if (arm->state() != dev::DeviceState::kActive)
    return failed_precondition("the arm is not active (" +
                               std::string(dev::to_string(arm->state())) + ")");
  dev::ArmCommand cmd;
  cmd.type = dev::ArmCommand::Type::kMoveTo;
  cmd.target = pose;
  cmd.speed_m_s = std::min(kRetractSpeedMps, arm->limits().max_speed_m_s);
  cmd.sequence = ++arm_command_sequence;
  std::int64_t now = clock().now_ns();
  recorder->write(ch_arm_cmd, now, now, static_cast<std::uint32_t>(cmd.sequence),
                  to_bytes(session::to_json(cmd)));
  HC_RETURN_IF_ERROR(arm->write(cmd));
  double dist = 0.0;
  if (last_arm)
    dist = std::sqrt(std::pow(last_arm->pose.x_m - pose.x_m, 2) +
                     std::pow(last_arm->pose.y_m - pose.y_m, 2) +
                     std::pow(last_arm->pose.z_m - pose.z_m, 2));
  const std::int64_t deadline =
      now + static_cast<std::int64_t>((2.0 * dist / cmd.speed_m_s + 2.0) * 1e9);
  const double force_limit = std::max(trip->force_n, current_force()) + kRetractForceRiseN;
  const auto give_up = [&](const std::string& why) {
    (void)arm->stop();
    record_arm_stop(clock().now_ns());
    return Status(StatusCode::kCancelled, why);
  };
  std::int64_t next = now;
  while (true) {
    HC_RETURN_IF_ERROR(poll());  // keeps recording every stream
    HC_ASSIGN_OR_RETURN(dev::ArmState st, arm->read());
    record_arm_state(st);
    now = clock().now_ns();
    if (st.motion == dev::ArmMotion::kFault) return give_up("arm fault: " + st.fault);
    if (current_force() > force_limit)
      return give_up("the force rose to " + num(current_force()) + " N while retracting");
    if (ft != nullptr && now - last_ft_ns > safety->limits().stall_timeout_ns)
      return give_up("no force-torque sample while retracting");
    if (st.command_sequence >= cmd.sequence && st.motion == dev::ArmMotion::kHolding) return {};
    if (now > deadline) return give_up("the arm did not reach the retract pose in time");
    next += period_ns;
    if (next < now) next = now + period_ns;
    clock().sleep_until_ns(next);
  }
}

void Session::Impl::retract_after_trip() {
  if (!trip || arm == nullptr || !safe_pose) return;
  if (trip->kind != SafetyTrip::Kind::kOverForce && trip->kind != SafetyTrip::Kind::kWorkspace)
    return;  // estop: nothing moves; a stalled F/T stream or a failed device: not watched
  record_event("retract", "retracting to the press's start pose after the safety stop");
  const Status s = retract_to(*safe_pose);
  retract = Json{{"ok", s.ok()},
                 {"message", s.ok() ? "retracted to the press's start pose" : s.message()},
                 {"pose", pose_json(*safe_pose)},
                 {"force_n", current_force()}};
  record_event(s.ok() ? "retracted" : "retract_failed", retract["message"].get<std::string>());
}

}  // namespace hc::rig
