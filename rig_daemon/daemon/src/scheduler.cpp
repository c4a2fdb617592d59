#include "rig_daemon/daemon/scheduler.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "rig_daemon/devices/sim_scene.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"
#include "session_impl.h"

namespace hc::rig {

namespace {

// Below this force magnitude the probe is taken to be out of contact (the sim F/T noise is a few
// hundredths of a newton; ATI Nano25 resolution is 1/24 N, thesis 5.6).
constexpr double kContactForceN = 0.2;
// A step is reached when the force is within this fraction of the level below its target.
constexpr double kStepTolerance = 0.02;
// Probe increments while seeking a step's force stay within [step_m / 20, 5 step_m].
constexpr int kMaxSeekMovesPerStep = 40;
constexpr double kApproachSpeedMps = 0.05;
constexpr double kPressSpeedMps = 0.02;
// How long to wait for the frames and samples of one trigger edge.
constexpr std::int64_t kEdgeTimeoutNs = 2'000'000'000;
// How long to wait for a fresh F/T sample after an arm move. A stalled stream trips the safety
// check (stall_timeout_s) in the same loop first; this only bounds the wait when the control
// loop itself is slow (e.g. a heavily loaded machine), which is not a gap in the F/T stream.
constexpr std::int64_t kFtAfterMoveTimeoutNs = 1'000'000'000;
// Progress events at most this often.
constexpr std::int64_t kProgressPeriodNs = 100'000'000;

double norm3(const std::array<double, 3>& v) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

Json vec_json(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

Json mat_json(const Eigen::Matrix3d& m) {
  Json rows = Json::array();
  for (int i = 0; i < 3; ++i) rows.push_back(Json::array({m(i, 0), m(i, 1), m(i, 2)}));
  return rows;
}

std::string_view kSyncSchema =
    R"({"type":"object","title":"hardcopy.SyncRecord","properties":{)"
    R"("trigger_index":{"type":"integer"},"edge_host_ns":{"type":"integer","description":"host monotonic ns of the rising edge"},)"
    R"("complete":{"type":"boolean"},"frames":{"type":"object","description":"camera -> frame_index"},)"
    R"("missing_cameras":{"type":"array","items":{"type":"string"}},"ft_sequence":{"type":"integer"},)"
    R"("ft_error_ns":{"type":"integer","description":"F/T sample host time - edge host time, ns"},)"
    R"("force_n":{"type":"array","items":{"type":"number"},"description":"Fx Fy Fz, N"},)"
    R"("fsr_sequence":{"type":"integer"},"fsr_error_ns":{"type":"integer"},"fsr_raw":{"type":"integer"},)"
    R"("fsr_force_n":{"type":"number","description":"N"}}})";
std::string_view kStepSchema =
    R"({"type":"object","title":"hardcopy.Step","properties":{)"
    R"("host_ns":{"type":"integer"},"location":{"type":"integer"},"level":{"type":"integer"},)"
    R"("step":{"type":"integer"},"target_force_n":{"type":"number"},"force_n":{"type":"number"},)"
    R"("depth_m":{"type":"number"},"pose":{"type":"object"},"trigger_indices":{"type":"array","items":{"type":"integer"}},)"
    R"("board_pose":{"type":"integer","description":"calibration: index of the board pose"}}})";
std::string_view kEventSchema =
    R"({"type":"object","title":"hardcopy.Event","properties":{)"
    R"("host_ns":{"type":"integer"},"kind":{"type":"string"},"message":{"type":"string"}}})";
std::string_view kTruthSchema =
    R"({"type":"object","title":"hardcopy.GroundTruth","properties":{)"
    R"("host_ns":{"type":"integer"},"trigger_index":{"type":"integer"},"probe":{"type":"object"},)"
    R"("indentation_m":{"type":"number"},"force_n":{"type":"number","description":"true contact force, N"},)"
    R"("markers_m":{"type":"array","items":{"type":"array","items":{"type":"number"}}},)"
    R"("probe_tip_m":{"type":"array","items":{"type":"number"}},"probe_axis":{"type":"array","items":{"type":"number"}},)"
    R"("probe_radius_m":{"type":"number"},"probe_shown":{"type":"boolean"},)"
    R"("shaft_markers_m":{"type":"array","items":{"type":"array","items":{"type":"number"}}},"shaft_marker_radius_m":{"type":"number"},)"
    R"("cameras":{"type":"object","description":"camera -> {occluded: [marker index], out_of_view: [marker index], board_visible}"},)"
    R"("board":{"type":"object","description":"pose_index, cols, rows, square_m, R (rows), t_m: x_world = R x_board + t"}}})";

}  // namespace

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

// ---- setup ----------------------------------------------------------------------------------

Status Session::Impl::setup() {
  const Plan& plan = opts.plan;
  const RigConfig& cfg = rig.config();
  period_ns = static_cast<std::int64_t>(std::llround(cfg.control_period_s * 1e9));
  std::vector<std::string> cam_names;
  Associator::Options ao;
  if (plan.protocol == Protocol::kHandHeld) {
    cam_names = plan.hand_held.cameras;
    trigger = rig.get<dev::Trigger>(cfg.first(DeviceKind::kTrigger)->name);
    fsr = rig.get<dev::Fsr>(plan.hand_held.fsr);
    ao.want_fsr = true;
    HC_ASSIGN_OR_RETURN(SafetyLimits limits, combine_limits(cfg.workspace, cfg.max_force_n,
                                                            cfg.stall_timeout_s, nullptr, nullptr));
    safety = std::make_unique<SafetyMonitor>(limits);
  } else if (plan.protocol == Protocol::kCalibration) {
    const CalibrationPlan& p = plan.calibration;
    cam_names = p.cameras;
    trigger = rig.get<dev::Trigger>(p.trigger_device.empty() ? cfg.first(DeviceKind::kTrigger)->name
                                                             : p.trigger_device);
    HC_ASSIGN_OR_RETURN(SafetyLimits limits, combine_limits(cfg.workspace, cfg.max_force_n,
                                                            cfg.stall_timeout_s, nullptr, nullptr));
    safety = std::make_unique<SafetyMonitor>(limits);
  } else {
    const AutomatedPlan& p = plan.automated;
    cam_names = p.cameras;
    trigger = rig.get<dev::Trigger>(p.trigger_device);
    ft = rig.get<dev::ForceTorque>(p.force_torque);
    arm = rig.get<dev::Arm>(p.arm);
    ao.want_ft = true;
    HC_ASSIGN_OR_RETURN(SafetyLimits limits,
                        combine_limits(cfg.workspace, cfg.max_force_n, cfg.stall_timeout_s,
                                       &p.workspace, &p.max_force_n));
    safety = std::make_unique<SafetyMonitor>(limits);
  }
  for (const std::string& c : cam_names) cameras.push_back(rig.get<dev::Camera>(c));
  session_cameras = std::set<std::string>(cam_names.begin(), cam_names.end());
  ao.cameras = cam_names;
  assoc = std::make_unique<Associator>(ao);

  used.clear();
  if (trigger) used.push_back(trigger);
  for (dev::Camera* c : cameras) used.push_back(c);
  if (ft) used.push_back(ft);
  if (fsr) used.push_back(fsr);
  if (arm) used.push_back(arm);

  // The file and its channels.
  std::error_code ec;
  std::filesystem::create_directories(opts.path.parent_path(), ec);
  HC_ASSIGN_OR_RETURN(recorder, Recorder::open(opts.path, opts.recorder));
  const auto meta = [](const dev::Device& d) {
    return rec::StringMap{{"device", d.name()},
                          {"kind", std::string(dev::to_string(d.kind()))},
                          {"backend", d.backend()}};
  };
  const rec::StringMap session_meta{{"device", "session"}, {"kind", "session"}, {"backend", ""}};
  if (trigger) {
    const auto& s = session::trigger_edge_schema();
    HC_ASSIGN_OR_RETURN(ch_edges,
                        recorder->add_json_channel(session::trigger_topic(trigger->name()), s.name,
                                                   s.json_schema, meta(*trigger)));
  }
  for (dev::Camera* c : cameras) {
    rec::StringMap m = meta(*c);
    const dev::CameraInfo info = c->camera_info();
    m["width"] = std::to_string(info.width);
    m["height"] = std::to_string(info.height);
    m["format"] = std::string(dev::to_string(info.format));
    m["trigger_mode"] = std::string(dev::to_string(info.trigger_mode));
    HC_ASSIGN_OR_RETURN(std::uint16_t id,
                        recorder->add_image_channel(session::camera_topic(c->name()), m));
    ch_cams.push_back(id);
  }
  if (ft) {
    const auto& s = session::wrench_sample_schema();
    rec::StringMap m = meta(*ft);
    m["counts_per_n"] = std::to_string(ft->calibration().counts_per_n);
    m["counts_per_nm"] = std::to_string(ft->calibration().counts_per_nm);
    m["sample_rate_hz"] = std::to_string(ft->sample_rate_hz());
    HC_ASSIGN_OR_RETURN(ch_ft, recorder->add_json_channel(session::wrench_topic(ft->name()), s.name,
                                                          s.json_schema, m));
  }
  if (fsr) {
    const auto& s = session::fsr_sample_schema();
    HC_ASSIGN_OR_RETURN(ch_fsr, recorder->add_json_channel(session::fsr_topic(fsr->name()), s.name,
                                                           s.json_schema, meta(*fsr)));
  }
  if (arm) {
    const auto& s = session::arm_state_schema();
    HC_ASSIGN_OR_RETURN(ch_arm_state,
                        recorder->add_json_channel(session::arm_state_topic(arm->name()), s.name,
                                                   s.json_schema, meta(*arm)));
    const auto& c = session::arm_command_schema();
    HC_ASSIGN_OR_RETURN(ch_arm_cmd,
                        recorder->add_json_channel(session::arm_command_topic(arm->name()), c.name,
                                                   c.json_schema, meta(*arm)));
  }
  HC_ASSIGN_OR_RETURN(
      ch_sync, recorder->add_json_channel(session::kSyncTopic, "hardcopy.SyncRecord", kSyncSchema,
                                          session_meta));
  HC_ASSIGN_OR_RETURN(ch_steps, recorder->add_json_channel(session::kStepsTopic, "hardcopy.Step",
                                                           kStepSchema, session_meta));
  HC_ASSIGN_OR_RETURN(ch_events, recorder->add_json_channel(session::kEventsTopic, "hardcopy.Event",
                                                            kEventSchema, session_meta));
  have_truth = rig.world() != nullptr;
  if (have_truth) {
    HC_ASSIGN_OR_RETURN(
        ch_truth,
        recorder->add_json_channel(
            session::kGroundTruthTopic, "hardcopy.GroundTruth", kTruthSchema,
            rec::StringMap{{"device", "world"}, {"kind", "ground_truth"}, {"backend", "sim"}}));
  }

  // Opening metadata: rig config, plan, specimen, software, calibration.
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(
      rec::kMetadataRigConfig, {{"yaml", cfg.source_text}, {"source", cfg.source_name}}));
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(
      rec::kMetadataPlan, {{"yaml", plan.source_text}, {"json", plan.to_json().dump()}}));
  rec::StringMap specimen(plan.specimen.begin(), plan.specimen.end());
  if (rig.world() != nullptr) specimen["simulated_specimen"] = rig.world()->specimen().name();
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(rec::kMetadataSpecimen, specimen));
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(
      rec::kMetadataSoftware, {{"name", "hardcopy rigd"}, {"version", opts.software_version}}));
  Json calib = Json::object();
  if (ft)
    calib[ft->name()] = {{"counts_per_n", ft->calibration().counts_per_n},
                         {"counts_per_nm", ft->calibration().counts_per_nm}};
  if (fsr) {
    const dev::FsrCalibration c = fsr->calibration();
    calib[fsr->name()] = {{"full_scale", c.full_scale},
                          {"threshold", c.threshold},
                          {"scale_n", c.scale_n},
                          {"exponent", c.exponent}};
  }
  for (dev::Camera* c : cameras) {
    const dev::CameraInfo i = c->camera_info();
    calib[c->name()] = {{"width", i.width},
                        {"height", i.height},
                        {"format", dev::to_string(i.format)},
                        {"exposure_s", i.exposure_s}};
  }
  HC_RETURN_IF_ERROR(
      recorder->write_metadata_now(rec::kMetadataCalibration, {{"json", calib.dump()}}));
  if (rig.world() != nullptr) {
    // The true parameters of the session's simulated cameras (rig_daemon/session/topics.h).
    Json sim_cams = Json::object();
    for (const dev::sim::CameraRecord& r : rig.world()->cameras()) {
      if (!session_cameras.count(r.name)) continue;
      const dev::sim::PinholeCamera& c = r.camera;
      sim_cams[r.name] = {{"width", c.width},
                          {"height", c.height},
                          {"fx", c.fx},
                          {"fy", c.fy},
                          {"cx", c.cx},
                          {"cy", c.cy},
                          {"distortion", c.distortion},
                          {"R", mat_json(c.R_cam_world)},
                          {"t_m", vec_json(c.t_cam_world)},
                          {"center_m", vec_json(c.center_world())}};
    }
    HC_RETURN_IF_ERROR(
        recorder->write_metadata_now(session::kMetadataSimCameras, {{"json", sim_cams.dump()}}));
    if (plan.protocol == Protocol::kCalibration) {
      const CalibrationPlan& p = plan.calibration;
      dev::sim::BoardShow show;
      show.spec.cols = p.board_cols;
      show.spec.rows = p.board_rows;
      show.spec.square_m = p.square_m;
      show.spec.margin_squares = p.margin_squares;
      dev::sim::BoardMotion motion;
      motion.poses = p.poses;
      motion.seed = p.seed;
      motion.max_tilt_deg = p.max_tilt_deg;
      const dev::sim::Specimen& spec = rig.world()->specimen();
      const Eigen::Vector2d c = spec.footprint().center();
      show.poses =
          dev::sim::board_poses(show.spec, motion, Eigen::Vector3d(c.x(), c.y(), spec.top_z_m()));
      show.dwell_ns = std::max<std::int64_t>(1, std::llround(p.dwell_s * 1e9));
      Json poses = Json::array();
      for (const dev::sim::BoardPose& b : show.poses)
        poses.push_back({{"R", mat_json(b.R)}, {"t_m", vec_json(b.t)}});
      const Json board{{"cols", p.board_cols},   {"rows", p.board_rows},
                       {"square_m", p.square_m}, {"margin_squares", p.margin_squares},
                       {"seed", p.seed},         {"poses", std::move(poses)}};
      HC_RETURN_IF_ERROR(
          recorder->write_metadata_now(session::kMetadataSimBoard, {{"json", board.dump()}}));
      board_show = std::move(show);
    }
  }
  recorder->start();

  if (have_truth) {
    rig.world()->set_ground_truth_callback([this](const dev::sim::GroundTruth& t) {
      Json j{{"host_ns", t.host_ns},
             {"probe", pose_json(t.probe)},
             {"indentation_m", t.indentation_m},
             {"force_n", t.force_n}};
      if (t.trigger_index) j["trigger_index"] = *t.trigger_index;
      Json markers = Json::array();
      for (const auto& m : t.markers_m) markers.push_back(vec_json(m));
      j["markers_m"] = std::move(markers);
      const dev::sim::ProbeGeometry& g = t.probe_geometry;
      j["probe_tip_m"] = vec_json(g.tip_m);
      j["probe_axis"] = vec_json(g.axis);
      j["probe_radius_m"] = g.radius_m;
      j["probe_shown"] = t.probe_shown;
      j["shaft_markers_m"] = Json::array({vec_json(g.markers_m[0]), vec_json(g.markers_m[1])});
      j["shaft_marker_radius_m"] = g.marker_radius_m;
      Json cams = Json::object();
      for (const dev::sim::CameraTruth& c : t.cameras) {
        if (!session_cameras.count(c.camera)) continue;
        cams[c.camera] = {{"occluded", c.occluded},
                          {"out_of_view", c.out_of_view},
                          {"board_visible", c.board_visible}};
      }
      j["cameras"] = std::move(cams);
      if (t.board_pose_index) {
        j["board"] = {{"pose_index", *t.board_pose_index}, {"cols", t.board_spec.cols},
                      {"rows", t.board_spec.rows},         {"square_m", t.board_spec.square_m},
                      {"R", mat_json(t.board_pose.R)},     {"t_m", vec_json(t.board_pose.t)}};
      }
      recorder->write(ch_truth, t.host_ns, t.host_ns,
                      static_cast<std::uint32_t>(t.trigger_index.value_or(0)),
                      rec::json_message(j));
    });
  }

  // Start the devices (a device left in error by an earlier session is reset first).
  // The trigger stays active from its first session on: its edge indices then count from the
  // daemon's first session, the same numbering hardware-triggered cameras and triggered FSRs use
  // for Frame/FsrSample::trigger_index (a re-activated simulated trigger would restart at 0 while
  // the cameras keep counting).
  for (dev::Device* d : used) {
    if (d->state() == dev::DeviceState::kError) HC_RETURN_IF_ERROR(d->reset());
    if (d == trigger && d->state() == dev::DeviceState::kActive) continue;
    if (d->state() == dev::DeviceState::kActive) HC_RETURN_IF_ERROR(d->deactivate());
    HC_RETURN_IF_ERROR(d->activate());
  }
  return {};
}

// ---- the control cycle ----------------------------------------------------------------------

void Session::Impl::record_event(std::string_view kind, const std::string& message) {
  const std::int64_t now = clock().now_ns();
  recorder->write(ch_events, now, now, 0,
                  rec::json_message(Json{{"host_ns", now}, {"kind", kind}, {"message", message}}));
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
                    static_cast<std::uint32_t>(r.trigger_index), rec::json_message(r.to_json()));
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
        Json step{{"host_ns", now},
                  {"location", li},
                  {"level", lv},
                  {"step", k},
                  {"target_force_n", target},
                  {"force_n", current_force()},
                  {"depth_m", depth},
                  {"pose", pose_json(at_depth(depth))},
                  {"trigger_indices", indices}};
        recorder->write(ch_steps, now, now, static_cast<std::uint32_t>(k), rec::json_message(step));
      }
      // Retract before the next level or location.
      HC_RETURN_IF_ERROR(move_to(start, kApproachSpeedMps));
    }
  }
  return {};
}

Status Session::Impl::run_calibration() {
  // One trigger pulse per board pose; between pulses the board moves (simulated rigs: the world
  // shows the pose the frame's trigger index selects) or a technician moves it (dwell_s).
  const CalibrationPlan& p = opts.plan.calibration;
  if (board_show) {
    board_show->first_trigger_index = rig.world()->pulses_by(clock().now_ns());
    board_show->start_ns = clock().now_ns();
    rig.world()->show_board(*board_show);
  }
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
    Json step{{"host_ns", now}, {"board_pose", k}, {"step", k + 1}, {"trigger_indices", indices}};
    recorder->write(ch_steps, now, now, static_cast<std::uint32_t>(k + 1), rec::json_message(step));
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

// ---- run / finish -----------------------------------------------------------------------------

Json Session::Impl::finish(Status run_status) {
  // Collect what is still in flight (a last cycle without advancing the protocol), close records.
  if (!trip) (void)poll();
  // The arm's last state (after a stop: that it stopped, and where).
  if (arm != nullptr && arm->state() == dev::DeviceState::kActive)
    if (Result<dev::ArmState> st = arm->read(); st.ok()) record_arm_state(*st);
  for (SyncRecord& r : assoc->take_all()) {
    recorder->write(ch_sync, r.edge_host_ns, r.edge_host_ns,
                    static_cast<std::uint32_t>(r.trigger_index), rec::json_message(r.to_json()));
    std::lock_guard lock(progress_mutex);
    ++done;
  }
  if (trigger != nullptr && trigger->state() == dev::DeviceState::kActive) (void)trigger->stop();
  for (dev::Device* d : used)
    if (d != trigger) (void)d->deactivate();
  if (have_truth) rig.world()->set_ground_truth_callback(nullptr);
  if (board_show) rig.world()->hide_board();

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
    if (m.have_truth && m.rig.world()) m.rig.world()->set_ground_truth_callback(nullptr);
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
