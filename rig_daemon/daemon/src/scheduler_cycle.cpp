// The scheduler's control cycle: draining the devices into the recording and the association,
// the session's events, waiting with pause points, and progress.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "session_impl.h"

namespace hc::rig {

// ---- the control cycle ----------------------------------------------------------------------

void Session::Impl::record_event(std::string_view kind, const std::string& message) {
  const std::int64_t now = clock().now_ns();
  session::EventRecord event;
  event.host_ns = now;
  event.kind = kind;
  event.message = message;
  recorder->write(ch_events, now, now, 0, to_bytes(session::to_json(event)));
  if (opts.on_event) opts.on_event("log", Json{{"kind", kind}, {"message", message}});
}

double Session::Impl::current_force() const {
  if (recent_force.empty()) return 0.0;
  double s = 0.0;
  for (double f : recent_force) s += f;
  return s / static_cast<double>(recent_force.size());
}

void Session::Impl::record_arm_state(const dev::ArmState& s) {
  recorder->write(ch_arm_state, s.host_ns, s.device_stamp_ns.value_or(s.host_ns),
                  static_cast<std::uint32_t>(s.sequence), to_bytes(session::to_json(s)));
  last_arm = s;
  if (opts.live) opts.live->set_arm(s);
}

Status Session::Impl::poll() {
  const std::int64_t now0 = clock().now_ns();
  if (estop_requested && !trip) {
    SafetyTrip t;
    t.kind = SafetyTrip::Kind::kEstop;
    t.message = "emergency stop requested";
    t.detected_ns = now0;
    t.sample_host_ns = now0;
    handle_trip(t);
  }
  const auto device_failed = [&](dev::Device& d, const Status& s) {
    SafetyTrip t;
    t.kind = SafetyTrip::Kind::kDeviceError;
    t.message = std::string(dev::to_string(d.kind())) + " '" + d.name() + "': " + s.message();
    t.detected_ns = clock().now_ns();
    t.sample_host_ns = t.detected_ns;
    handle_trip(t);
  };
  if (trigger) {
    edges_buf.clear();
    Result<std::size_t> n = trigger->read(edges_buf, dev::Duration(0));
    if (!n.ok()) {
      device_failed(*trigger, n.status());
    } else {
      for (const dev::TriggerEdge& e : edges_buf) {
        recorder->write(ch_edges, e.host_ns, e.device_stamp_ns.value_or(e.host_ns),
                        static_cast<std::uint32_t>(e.device_counter),
                        to_bytes(session::to_json(e)));
        assoc->add_edge(e);
        if (e.rising) {
          ++edges_received;
          last_edge_index = e.index;
        }
      }
    }
  }
  if (ft) {
    ft_buf.clear();
    Result<std::size_t> n = ft->read(ft_buf, dev::Duration(0));
    if (!n.ok()) {
      device_failed(*ft, n.status());
    } else {
      for (const dev::WrenchSample& s : ft_buf) {
        // Safety first: the stop goes out before the sample is even queued for the disk.
        if (std::optional<SafetyTrip> t = safety->check_wrench(s, clock().now_ns()))
          handle_trip(*t);
        recorder->write(ch_ft, s.host_ns, s.device_stamp_ns.value_or(s.host_ns), s.rdt_sequence,
                        to_bytes(session::to_json(s)));
        assoc->add_wrench(s);
        last_ft_ns = s.host_ns;
        recent_force.push_back(norm3(s.force_n));
        if (recent_force.size() > kForceWindow) recent_force.pop_front();
      }
      if (opts.live) opts.live->add_wrenches(ft_buf);
    }
    // The stall check right after the read: time spent below on other devices (simulated
    // cameras render their frames inside read()) is not a gap in the F/T stream.
    if (!trip) {
      if (std::optional<SafetyTrip> t = safety->check_stall(armed_since_ns >= 0, last_ft_ns,
                                                            armed_since_ns, clock().now_ns()))
        handle_trip(*t);
    }
  }
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    frames_buf.clear();
    Result<std::size_t> n = cameras[i]->read(frames_buf, dev::Duration(0));
    if (!n.ok()) {
      device_failed(*cameras[i], n.status());
      continue;
    }
    for (const dev::Frame& f : frames_buf) {
      const std::int64_t stamp = f.device_stamp_ns.value_or(f.host_ns);
      rec::encode_raw_image_view(stamp, cameras[i]->name(), f.width, f.height,
                                 dev::foxglove_encoding(f.format), f.stride_bytes,
                                 rec::ByteSpan(f.pixels.data(), f.pixels.size()), image_buf);
      if (opts.live) opts.live->offer_frame(cameras[i]->name(), f);
      recorder->write(ch_cams[i], f.host_ns, stamp, static_cast<std::uint32_t>(f.frame_id),
                      image_buf);
      assoc->add_frame(cameras[i]->name(), f);
    }
  }
  if (fsr) {
    fsr_buf.clear();
    Result<std::size_t> n = fsr->read(fsr_buf, dev::Duration(0));
    if (!n.ok()) {
      device_failed(*fsr, n.status());
    } else {
      for (const dev::FsrSample& s : fsr_buf) {
        recorder->write(ch_fsr, s.host_ns, s.device_stamp_ns.value_or(s.host_ns),
                        static_cast<std::uint32_t>(s.sequence), to_bytes(session::to_json(s)));
        assoc->add_fsr(s);
      }
    }
  }
  const std::int64_t now = clock().now_ns();
  for (SyncRecord& r : assoc->take_ready(now)) {
    recorder->write(ch_sync, r.edge_host_ns, r.edge_host_ns,
                    static_cast<std::uint32_t>(r.trigger_index), to_bytes(session::to_json(r)));
    std::lock_guard lock(progress_mutex);
    ++done;
  }
  if (Status e = recorder->error(); !e.ok()) return e.with_context("recording");
  return {};
}

Status Session::Impl::cycle() {
  const std::int64_t woke_ns = clock().now_ns();
  HC_RETURN_IF_ERROR(poll());
  update_progress(false);
  if (trip) return Status(StatusCode::kCancelled, trip->message);
  if (stop_requested) return Status(StatusCode::kCancelled, "stopped on request");
  const std::int64_t now = clock().now_ns();
  if (last_cycle_ns >= 0) max_cycle_gap_ns = std::max(max_cycle_gap_ns, now - last_cycle_ns);
  if (opts.live && last_cycle_ns >= 0) opts.live->add_cycle(now - last_cycle_ns, now - woke_ns);
  last_cycle_ns = now;
  next_cycle_ns += period_ns;
  if (next_cycle_ns < now) next_cycle_ns = now + period_ns;  // fell behind: do not burst
  clock().sleep_until_ns(next_cycle_ns);
  return {};
}

Status Session::Impl::wait_for(const std::function<bool()>& pred, std::int64_t timeout_ns,
                               std::string_view what) {
  const std::int64_t deadline = clock().now_ns() + timeout_ns;
  while (true) {
    HC_RETURN_IF_ERROR(cycle());
    if (pred()) return {};
    if (clock().now_ns() > deadline)
      return Status(StatusCode::kDeadlineExceeded, "timed out waiting for " + std::string(what));
  }
}

Status Session::Impl::pause_point() {
  if (!pause_requested) return {};
  self.state_ = SessionState::kPaused;
  record_event("pause", "paused on request");
  update_progress(true);
  while (pause_requested) HC_RETURN_IF_ERROR(cycle());
  self.state_ = SessionState::kRunning;
  record_event("resume", "resumed on request");
  update_progress(true);
  return {};
}

void Session::Impl::update_progress(bool force_event) {
  const std::int64_t now = clock().now_ns();
  if (!force_event && now - last_progress_ns < kProgressPeriodNs) return;
  last_progress_ns = now;
  Json j;
  {
    std::lock_guard lock(progress_mutex);
    j = Json{{"session", opts.path.string()},
             {"plan", opts.plan.name},
             {"protocol", to_string(opts.plan.protocol)},
             {"done", done},
             {"total", total},
             {"step", step_text},
             {"force_n", current_force()},
             {"elapsed_s", double(now - start_ns) * 1e-9},
             {"association", assoc->stats().to_json()}};
    if (trip) j["trip"] = trip->to_json();
    progress_json = j;
  }
  j["state"] = to_string(self.state_.load());
  if (opts.on_event) opts.on_event("progress", j);
}

}  // namespace hc::rig
