// The session's setup (Session::Impl::setup): the devices it uses, the channel table of the
// recording (one channel per device stream and the session's own channels, rig_daemon/session/
// topics.h) with their schemas, and the metadata written before the first sample.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"
#include "session_impl.h"

namespace hc::rig {

// ---- setup ----------------------------------------------------------------------------------

// The devices of the plan, the associator and the safety monitor.
Status Session::Impl::choose_devices() {
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
  return {};
}

Status Session::Impl::open_recording() {
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
  const auto add_session_channel = [&](std::string_view topic, const session::MessageSchema& c,
                                       const rec::StringMap& metadata) {
    return recorder->add_json_channel(topic, c.name, c.json_schema, metadata);
  };
  HC_ASSIGN_OR_RETURN(ch_sync, add_session_channel(session::kSyncTopic,
                                                   session::sync_record_schema(), session_meta));
  HC_ASSIGN_OR_RETURN(ch_steps, add_session_channel(session::kStepsTopic,
                                                    session::step_record_schema(), session_meta));
  HC_ASSIGN_OR_RETURN(ch_events, add_session_channel(session::kEventsTopic,
                                                     session::event_record_schema(), session_meta));
  source = rig.make_session_source();
  if (source) HC_RETURN_IF_ERROR(source->add_channels(*recorder));
  return {};
}

Status Session::Impl::write_opening_metadata() {
  const Plan& plan = opts.plan;
  const RigConfig& cfg = rig.config();
  // Opening metadata: rig config, plan, specimen, software, calibration.
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(
      rec::kMetadataRigConfig, {{"yaml", cfg.source_text}, {"source", cfg.source_name}}));
  HC_RETURN_IF_ERROR(recorder->write_metadata_now(
      rec::kMetadataPlan, {{"yaml", plan.source_text}, {"json", plan.to_json().dump()}}));
  rec::StringMap specimen(plan.specimen.begin(), plan.specimen.end());
  if (source) source->describe_specimen(specimen);
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
  if (source) HC_RETURN_IF_ERROR(source->write_metadata(plan, session_cameras));
  return {};
}

Status Session::Impl::setup() {
  HC_RETURN_IF_ERROR(choose_devices());
  HC_RETURN_IF_ERROR(open_recording());
  HC_RETURN_IF_ERROR(write_opening_metadata());
  recorder->start();

  if (source) source->start();

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

}  // namespace hc::rig
