// The plan modes the scheduler runs: hand-held capture, the automated press protocol (with its
// arm moves and trigger bursts), the board calibration and replay.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "session_impl.h"

namespace hc::rig {

// ---- protocols ------------------------------------------------------------------------------

Status Session::Impl::run_hand_held() {
  const HandHeldPlan& p = opts.plan.hand_held;
  std::uint64_t remaining = static_cast<std::uint64_t>(opts.plan.expected_triggers());
  const std::uint64_t target = remaining;
  const std::uint64_t first = edges_received;
  const double period_s = 1.0 / p.trigger.rate_hz;
  while (remaining > 0) {
    dev::PulseTrain train{p.trigger.rate_hz, p.trigger.pulse_width_s, remaining};
    HC_RETURN_IF_ERROR(trigger->start(train));
    {
      std::lock_guard lock(progress_mutex);
      step_text = "trigger " + std::to_string(p.trigger.rate_hz) + " Hz";
    }
    // Run until the train ends or a pause is asked for.
    const std::int64_t timeout =
        static_cast<std::int64_t>((static_cast<double>(remaining) * period_s + 5.0) * 1e9);
    HC_RETURN_IF_ERROR(wait_for([&] { return edges_received - first >= target || pause_requested; },
                                timeout, "the trigger's pulses"));
    remaining = target - std::min(target, edges_received - first);
    if (pause_requested) {
      (void)trigger->stop();
      HC_RETURN_IF_ERROR(pause_point());
      // Edges fired before the stop took effect still arrive.
      HC_RETURN_IF_ERROR(cycle());
      remaining = target - std::min(target, edges_received - first);
    }
  }
  // Wait for the last frames and samples.
  return wait_for([&] { return assoc->idle(); }, kEdgeTimeoutNs + 100'000'000,
                  "the last frames and samples");
}

Status Session::Impl::move_to(const dev::ArmPose& pose, double speed) {
  if (Status s = safety->check_target(pose); !s.ok()) {
    SafetyTrip t;
    t.kind = SafetyTrip::Kind::kWorkspace;
    t.message = s.message();
    t.detected_ns = clock().now_ns();
    t.sample_host_ns = t.detected_ns;
    handle_trip(t);
    return Status(StatusCode::kCancelled, s.message());
  }
  dev::ArmCommand cmd;
  cmd.type = dev::ArmCommand::Type::kMoveTo;
  cmd.target = pose;
  cmd.speed_m_s = std::min(speed, arm->limits().max_speed_m_s);
  cmd.sequence = ++arm_command_sequence;
  const std::int64_t now = clock().now_ns();
  recorder->write(ch_arm_cmd, now, now, static_cast<std::uint32_t>(cmd.sequence),
                  to_bytes(session::to_json(cmd)));
  HC_RETURN_IF_ERROR(arm->write(cmd));
  double dist = 0.0;
  if (last_arm) {
    const dev::ArmPose& a = last_arm->pose;
    dist = std::sqrt((a.x_m - pose.x_m) * (a.x_m - pose.x_m) +
                     (a.y_m - pose.y_m) * (a.y_m - pose.y_m) +
                     (a.z_m - pose.z_m) * (a.z_m - pose.z_m));
  }
  const auto timeout = static_cast<std::int64_t>((2.0 * dist / cmd.speed_m_s + 2.0) * 1e9);
  Status arm_error;
  HC_RETURN_IF_ERROR(wait_for(
      [&] {
        Result<dev::ArmState> st = arm->read();
        if (!st.ok()) {
          arm_error = st.status();
          return true;
        }
        record_arm_state(*st);
        if (st->motion == dev::ArmMotion::kFault) {
          arm_error = Status(StatusCode::kUnavailable, "arm fault: " + st->fault);
          return true;
        }
        return st->command_sequence >= cmd.sequence && st->motion == dev::ArmMotion::kHolding;
      },
      timeout, "the arm to reach its target"));
  return arm_error;
}

Status Session::Impl::fire_and_collect(std::vector<std::uint64_t>& indices, int pulses) {
  for (int f = 0; f < pulses; ++f) {
    const std::uint64_t before = edges_received;
    HC_RETURN_IF_ERROR(trigger->fire());
    HC_RETURN_IF_ERROR(
        wait_for([&] { return edges_received > before; }, kEdgeTimeoutNs, "the trigger edge"));
    const std::uint64_t index = *last_edge_index;
    indices.push_back(index);
    // Wait until its frames and force sample are in (or the associator gave up on them).
    Status s = wait_for([&] { return assoc->complete(index) || assoc->idle(); }, kEdgeTimeoutNs,
                        "the frames of a trigger edge");
    if (s.code() == StatusCode::kDeadlineExceeded) {
      record_event("late", "trigger edge " + std::to_string(index) + ": " + s.message());
      continue;
    }
    HC_RETURN_IF_ERROR(s);
  }
  return {};
}

Status Session::Impl::run_automated() {
  const AutomatedPlan& p = opts.plan.automated;
  HC_RETURN_IF_ERROR(check_start_conditions());
  // Home the arm if needed.
  HC_ASSIGN_OR_RETURN(dev::ArmState st, arm->read());
  record_arm_state(st);
  if (!st.homed) {
    dev::ArmCommand home;
    home.type = dev::ArmCommand::Type::kHome;
    home.sequence = ++arm_command_sequence;
    const std::int64_t now = clock().now_ns();
    recorder->write(ch_arm_cmd, now, now, static_cast<std::uint32_t>(home.sequence),
                    to_bytes(session::to_json(home)));
    HC_RETURN_IF_ERROR(arm->write(home));
    Status arm_error;
    HC_RETURN_IF_ERROR(wait_for(
        [&] {
          Result<dev::ArmState> s = arm->read();
          if (!s.ok()) {
            arm_error = s.status();
            return true;
          }
          record_arm_state(*s);
          return s->homed && s->motion != dev::ArmMotion::kHoming;
        },
        60'000'000'000, "the arm to home"));
    HC_RETURN_IF_ERROR(arm_error);
  }
  // Tare the force sensor away from the specimen, then watch its stream from here on.
  HC_RETURN_IF_ERROR(ft->bias());
  armed_since_ns = clock().now_ns();
  HC_RETURN_IF_ERROR(wait_for([&] { return last_ft_ns >= armed_since_ns; },
                              std::max<std::int64_t>(safety->limits().stall_timeout_ns, 1), "F/T"));
  recent_force.clear();

  for (std::size_t li = 0; li < p.locations.size(); ++li) {
    const ProbeLocation& loc = p.locations[li];
    const dev::ArmPose start{loc.position_m[0], loc.position_m[1], loc.position_m[2], 0.0};
    const auto at_depth = [&](double d) {
      return dev::ArmPose{start.x_m + loc.direction[0] * d, start.y_m + loc.direction[1] * d,
                          start.z_m + loc.direction[2] * d, 0.0};
    };
    for (std::size_t lv = 0; lv < p.force_levels_n.size(); ++lv) {
      const double level = p.force_levels_n[lv];
      HC_RETURN_IF_ERROR(pause_point());
      HC_RETURN_IF_ERROR(move_to(start, kApproachSpeedMps));
      safe_pose = start;  // clear of the specimen: where a safety stop retracts to
      double depth = 0.0;
      // A force the press cannot reach within max_depth_m fails the session (the probe missed
      // the specimen, or it is softer than the plan assumed); the probe is retracted first.
      const auto not_reached = [&](const std::string& what) -> Status {
        const std::string where =
            "location " + std::to_string(li) + " (" + num(loc.position_m[0] * 1e3) + ", " +
            num(loc.position_m[1] * 1e3) + ", " + num(loc.position_m[2] * 1e3) + " mm), level " +
            std::to_string(lv) + " (" + num(level) + " N): ";
        record_event("not_reached", where + what);
        HC_RETURN_IF_ERROR(move_to(start, kApproachSpeedMps));
        return failed_precondition(where + what);
      };
      // Approach: advance in step_m increments until the probe touches the specimen.
      {
        std::lock_guard lock(progress_mutex);
        step_text = "location " + std::to_string(li + 1) + ": approaching";
      }
      while (current_force() < kContactForceN) {
        if (depth + p.step_m > p.max_depth_m)
          return not_reached("no contact within max_depth_m = " + num(p.max_depth_m * 1e3) +
                             " mm (force " + num(current_force()) +
                             " N): the probe does not reach the specimen along its direction");
        depth += p.step_m;
        HC_RETURN_IF_ERROR(move_to(at_depth(depth), kPressSpeedMps));
        const std::int64_t t_moved = clock().now_ns();
        HC_RETURN_IF_ERROR(wait_for([&] { return last_ft_ns > t_moved + 1'000'000; },
                                    kFtAfterMoveTimeoutNs, "F/T after a move"));
      }
      double prev_depth = depth, prev_force = current_force();
      double stiffness = 0.0;  // N/m, from the last move in contact
      for (int k = 1; k <= p.steps; ++k) {
        HC_RETURN_IF_ERROR(pause_point());
        const double target = level * k / p.steps;
        {
          std::lock_guard lock(progress_mutex);
          step_text = "location " + std::to_string(li + 1) + "/" +
                      std::to_string(p.locations.size()) + ", level " + std::to_string(lv + 1) +
                      "/" + std::to_string(p.force_levels_n.size()) + ", step " +
                      std::to_string(k) + "/" + std::to_string(p.steps);
        }
        const auto reached = [&] { return current_force() >= target - kStepTolerance * level; };
        for (int m = 0; m < kMaxSeekMovesPerStep && !reached(); ++m) {
          const double f = current_force();
          double inc = p.step_m;
          if (f > kContactForceN && stiffness > 0.0) inc = (target - f) / stiffness;
          inc = std::clamp(inc, p.step_m / 20.0, 5.0 * p.step_m);
          if (depth + inc > p.max_depth_m) break;
          prev_depth = depth;
          prev_force = f;
          depth += inc;
          HC_RETURN_IF_ERROR(move_to(at_depth(depth), kPressSpeedMps));
          // Let the F/T window fill with samples taken at the new depth.
          const std::int64_t t_moved = clock().now_ns();
          HC_RETURN_IF_ERROR(wait_for([&] { return last_ft_ns > t_moved + 1'000'000; },
                                      kFtAfterMoveTimeoutNs, "F/T after a move"));
          const double f_new = current_force();
          if (f_new > kContactForceN && prev_force > kContactForceN && depth > prev_depth)
            stiffness = std::max(1.0, (f_new - prev_force) / (depth - prev_depth));
          else if (f_new > kContactForceN)
            stiffness = std::max(1.0, f_new / inc);
        }
        if (!reached())
          return not_reached("step " + std::to_string(k) + "/" + std::to_string(p.steps) +
                             ": force " + num(current_force()) + " N below the target " +
                             num(target) + " N at depth " + num(depth * 1e3) + " mm (max_depth_m " +
                             num(p.max_depth_m * 1e3) + " mm)");
        if (p.settle_s > 0) {
          const std::int64_t until = clock().now_ns() + static_cast<std::int64_t>(p.settle_s * 1e9);
          HC_RETURN_IF_ERROR(wait_for([&] { return clock().now_ns() >= until; },
                                      static_cast<std::int64_t>(p.settle_s * 1e9) + 1'000'000'000,
                                      "settling"));
        }
        std::vector<std::uint64_t> indices;
        HC_RETURN_IF_ERROR(fire_and_collect(indices, p.frames_per_step));
        const std::int64_t now = clock().now_ns();
        session::StepRecord step;
        step.host_ns = now;
        step.step = k;
        step.trigger_indices = std::move(indices);
        step.location = static_cast<int>(li);
        step.level = static_cast<int>(lv);
        step.target_force_n = target;
        step.force_n = current_force();
        step.depth_m = depth;
        step.pose = at_depth(depth);
        recorder->write(ch_steps, now, now, static_cast<std::uint32_t>(k),
                        to_bytes(session::to_json(step)));
      }
      // Retract before the next level or location.
      HC_RETURN_IF_ERROR(move_to(start, kApproachSpeedMps));
    }
  }
  return {};
}

Status Session::Impl::run_calibration() {
  // One trigger pulse per board pose; between pulses the board moves (simulated rigs: the
  // session source shows the pose the frame's trigger index selects) or a technician moves it
  // (dwell_s).
  const CalibrationPlan& p = opts.plan.calibration;
  if (source) source->begin_calibration(clock().now_ns());
  for (int k = 0; k < p.poses; ++k) {
    HC_RETURN_IF_ERROR(pause_point());
    {
      std::lock_guard lock(progress_mutex);
      step_text = "board pose " + std::to_string(k + 1) + "/" + std::to_string(p.poses);
    }
    if (p.dwell_s > 0.0) {
      const auto dwell = static_cast<std::int64_t>(p.dwell_s * 1e9);
      const std::int64_t until = clock().now_ns() + dwell;
      HC_RETURN_IF_ERROR(wait_for([&] { return clock().now_ns() >= until; }, dwell + 1'000'000'000,
                                  "the board to move"));
    }
    std::vector<std::uint64_t> indices;
    HC_RETURN_IF_ERROR(fire_and_collect(indices, 1));
    const std::int64_t now = clock().now_ns();
    session::StepRecord step;
    step.host_ns = now;
    step.step = k + 1;
    step.trigger_indices = std::move(indices);
    step.board_pose = k;
    recorder->write(ch_steps, now, now, static_cast<std::uint32_t>(k + 1),
                    to_bytes(session::to_json(step)));
  }
  return {};
}

Status Session::Impl::run_replay() {
  // A replay cannot be commanded: record every stream the plan names until the recording ends
  // (the items keep their recorded times, counters and payloads, so the new session holds the
  // same messages on these channels).
  dev::ReplaySession& r = *rig.replay();
  {
    std::lock_guard lock(progress_mutex);
    step_text = "replaying " + std::to_string(double(r.end_ns() - r.start_ns()) * 1e-9) + " s";
  }
  bool reached_end = false;
  const std::int64_t timeout = r.due_clock_ns(r.end_ns()) - clock().now_ns() + 10'000'000'000;
  return wait_for(
      [&] {
        // One more cycle after the last recorded time is due, so its items are read.
        if (reached_end) return assoc->idle();
        reached_end = r.recorded_ns_at(clock().now_ns()) >= r.end_ns();
        return false;
      },
      timeout, "the end of the replayed session");
}

}  // namespace hc::rig
