#include "rig_daemon/daemon/scheduler.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"
#include "session_impl.h"

namespace hc::rig {

std::string_view to_string(SessionState s) {
  switch (s) {
    case SessionState::kIdle:
      return "idle";
    case SessionState::kStarting:
      return "starting";
    case SessionState::kRunning:
      return "running";
    case SessionState::kPaused:
      return "paused";
    case SessionState::kFinished:
      return "finished";
    case SessionState::kStopped:
      return "stopped";
    case SessionState::kAborted:
      return "aborted";
    case SessionState::kFailed:
      return "failed";
  }
  return "unknown";
}

// ------------------------------------------------------------------------------------------------

Status Session::validate(const Rig& rig, const Plan& plan) {
  const auto need = [&](const std::string& name, DeviceKind kind, std::string_view role) -> Status {
    const dev::Device* d = rig.find(name);
    if (d == nullptr)
      return invalid_argument("plan '" + plan.name + "': " + std::string(role) + " '" + name +
                              "' is not a device of this rig");
    if (d->kind() != kind)
      return invalid_argument("plan '" + plan.name + "': device '" + name + "' is a " +
                              std::string(dev::to_string(d->kind())) + ", not a " +
                              std::string(dev::to_string(kind)));
    return {};
  };
  const RigConfig& cfg = rig.config();
  if (plan.protocol == Protocol::kHandHeld) {
    for (const std::string& c : plan.hand_held.cameras)
      HC_RETURN_IF_ERROR(need(c, DeviceKind::kCamera, "camera"));
    HC_RETURN_IF_ERROR(need(plan.hand_held.fsr, DeviceKind::kFsr, "fsr"));
    if (cfg.first(DeviceKind::kTrigger) == nullptr)
      return invalid_argument("plan '" + plan.name + "': the rig has no trigger device");
    return {};
  }
  if (plan.protocol == Protocol::kCalibration) {
    const CalibrationPlan& c = plan.calibration;
    for (const std::string& cam : c.cameras)
      HC_RETURN_IF_ERROR(need(cam, DeviceKind::kCamera, "camera"));
    if (!c.trigger_device.empty())
      return need(c.trigger_device, DeviceKind::kTrigger, "trigger_device");
    if (cfg.first(DeviceKind::kTrigger) == nullptr)
      return invalid_argument("plan '" + plan.name + "': the rig has no trigger device");
    return {};
  }
  const AutomatedPlan& p = plan.automated;
  for (const std::string& c : p.cameras) HC_RETURN_IF_ERROR(need(c, DeviceKind::kCamera, "camera"));
  HC_RETURN_IF_ERROR(need(p.force_torque, DeviceKind::kForceTorque, "force_torque"));
  HC_RETURN_IF_ERROR(need(p.arm, DeviceKind::kArm, "arm"));
  HC_RETURN_IF_ERROR(need(p.trigger_device, DeviceKind::kTrigger, "trigger_device"));
  // The force limits are checked up front like the workspace: a plan that asks for more than the
  // rig allows is refused, not left to be stopped mid-press.
  if (p.max_force_n > cfg.max_force_n)
    return invalid_argument("plan '" + plan.name + "': max_force_n " + num(p.max_force_n) +
                            " N is above the rig's max_force_n " + num(cfg.max_force_n) + " N (" +
                            cfg.source_name + ")");
  HC_ASSIGN_OR_RETURN(SafetyLimits limits,
                      combine_limits(cfg.workspace, cfg.max_force_n, cfg.stall_timeout_s,
                                     &p.workspace, &p.max_force_n));
  SafetyMonitor monitor(limits);
  for (std::size_t i = 0; i < p.locations.size(); ++i) {
    const auto& l = p.locations[i];
    dev::ArmPose pose{l.position_m[0], l.position_m[1], l.position_m[2], 0.0};
    if (Status s = monitor.check_target(pose); !s.ok())
      return invalid_argument("plan '" + plan.name + "': locations[" + std::to_string(i) +
                              "]: " + s.message() + " (the rig's and the plan's boxes combined)");
  }
  return {};
}

Session::Session(Rig& rig, SessionOptions options)
    : impl_(std::make_unique<Impl>(*this, rig, std::move(options))) {}

Session::~Session() = default;

void Session::pause() { impl_->pause_requested = true; }
void Session::resume() { impl_->pause_requested = false; }
void Session::stop() { impl_->stop_requested = true; }
void Session::estop() {
  // Arm::stop() is safe from any thread; the session loop sees the flag within one cycle and
  // stops the trigger and the protocol too.
  impl_->estop_requested = true;
  if (impl_->arm != nullptr) {
    (void)impl_->arm->stop();
    impl_->estop_stop_ns = impl_->clock().now_ns();
  }
}

Json Session::progress() const {
  std::lock_guard lock(impl_->progress_mutex);
  Json j = impl_->progress_json;
  j["state"] = to_string(state_.load());
  return j;
}

// ---- run / finish -----------------------------------------------------------------------------

Json Session::Impl::finish(Status run_status) {
  // Collect what is still in flight (a last cycle without advancing the protocol), close records.
  if (!trip) (void)poll();
  // The arm's last state (after a stop: that it stopped, and where).
  if (arm != nullptr && arm->state() == dev::DeviceState::kActive)
    if (Result<dev::ArmState> st = arm->read(); st.ok()) record_arm_state(*st);
  for (SyncRecord& r : assoc->take_all()) {
    recorder->write(ch_sync, r.edge_host_ns, r.edge_host_ns,
                    static_cast<std::uint32_t>(r.trigger_index), to_bytes(session::to_json(r)));
    std::lock_guard lock(progress_mutex);
    ++done;
  }
  if (trigger != nullptr && trigger->state() == dev::DeviceState::kActive) (void)trigger->stop();
  for (dev::Device* d : used)
    if (d != trigger) (void)d->deactivate();
  if (source) source->stop();

  SessionState final_state = SessionState::kFinished;
  std::string reason = "completed";
  if (trip) {
    final_state = SessionState::kAborted;
    reason = std::string(to_string(trip->kind)) + ": " + trip->message;
  } else if (stop_requested) {
    final_state = SessionState::kStopped;
    reason = "stopped on request";
  } else if (!run_status.ok()) {
    final_state = SessionState::kFailed;
    reason = run_status.message();
  }
  if (!run_status.ok() && final_state == SessionState::kFailed) record_event("error", reason);

  rec::StringMap stats;
  Json devices_json = Json::object();
  for (dev::Device* d : used) {
    const dev::DeviceStats s = d->stats();
    stats[d->name() + ".received"] = std::to_string(s.received);
    stats[d->name() + ".lost"] = std::to_string(s.lost);
    stats[d->name() + ".late"] = std::to_string(s.late);
    stats[d->name() + ".incomplete"] = std::to_string(s.incomplete);
    devices_json[d->name()] = stats_json(s);
  }
  recorder->write_metadata(std::string(rec::kMetadataDeviceStats), stats);
  const AssociationStats& a = assoc->stats();
  const std::int64_t end_ns = clock().now_ns();
  Json summary{{"session", opts.path.string()},
               {"plan", opts.plan.name},
               {"protocol", to_string(opts.plan.protocol)},
               {"state", to_string(final_state)},
               {"reason", reason},
               {"duration_s", double(end_ns - start_ns) * 1e-9},
               {"expected_triggers", opts.plan.expected_triggers()},
               {"association", a.to_json()},
               {"devices", devices_json},
               {"control_period_s", rig.config().control_period_s},
               {"max_cycle_gap_ns", max_cycle_gap_ns}};
  if (trip) summary["trip"] = trip->to_json();
  if (!retract.is_null()) summary["retract"] = retract;
  if (opts.live) summary["cycle"] = opts.live->cycle_json();
  rec::StringMap session_meta{
      {"state", std::string(to_string(final_state))}, {"reason", reason}, {"json", summary.dump()}};
  recorder->write_metadata(std::string(session::kMetadataSession), session_meta);
  Result<rec::McapWriter::Summary> closed = recorder->close();
  if (!closed.ok()) {
    summary["state"] = to_string(SessionState::kFailed);
    summary["reason"] = "recording: " + closed.status().message();
    final_state = SessionState::kFailed;
  } else {
    summary["messages"] = closed->message_count;
    summary["file_size"] = closed->file_size;
  }
  self.state_ = final_state;
  {
    std::lock_guard lock(progress_mutex);
    progress_json = summary;
  }
  return summary;
}

Result<Json> Session::run() {
  Impl& m = *impl_;
  state_ = SessionState::kStarting;
  m.start_ns = m.clock().now_ns();
  m.next_cycle_ns = m.start_ns;
  m.total = m.opts.plan.expected_triggers();
  if (Status s = m.setup(); !s.ok()) {
    for (dev::Device* d : m.used) (void)d->deactivate();
    if (m.source) m.source->stop();
    if (m.recorder) {
      m.record_event("error", s.message());
      (void)m.recorder->close();
    }
    state_ = SessionState::kFailed;
    return s;
  }
  state_ = SessionState::kRunning;
  m.update_progress(true);
  Status s = m.rig.replay() != nullptr                        ? m.run_replay()
             : m.opts.plan.protocol == Protocol::kHandHeld    ? m.run_hand_held()
             : m.opts.plan.protocol == Protocol::kCalibration ? m.run_calibration()
                                                              : m.run_automated();
  m.retract_after_trip();
  Json summary = m.finish(s);
  if (m.opts.on_event) m.opts.on_event("finished", summary);
  return summary;
}

}  // namespace hc::rig
