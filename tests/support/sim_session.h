// Sessions recorded in-process by the rig daemon on simulated devices with simulated time, and the
// true calibration of their cameras: the setup of every test that tracks or calibrates from a
// recorded session. Include only from tests that link hardcopy_daemon and
// hardcopy_camera_calibration.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "camera/camera_model.h"
#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"
#include "rig_daemon/devices/clock.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/session/topics.h"

namespace hc::testing {

// Runs `plan` on a daemon built from `cfg` (sessions written to `sessions_dir`) on a simulated
// clock; returns the recorded session's path once the plan has finished.
inline Result<std::filesystem::path> record_simulated_session(
    rig::RigConfig cfg, const rig::Plan& plan, const std::filesystem::path& sessions_dir,
    int timeout_ms = 1'800'000) {
  cfg.sessions_dir = sessions_dir;
  rig::Daemon::Options o;
  o.config = std::move(cfg);
  o.clock = std::make_shared<devices::SimulatedClock>(1'000'000'000);
  o.software_version = "test";
  HC_ASSIGN_OR_RETURN(std::unique_ptr<rig::Daemon> d, rig::Daemon::create(o));
  HC_ASSIGN_OR_RETURN(Json started, d->start(plan));
  (void)started;
  if (!d->wait_idle(timeout_ms)) return internal_error("the session did not finish in time");
  const Json s = d->last_summary();
  if (s["state"] != "finished" || !s.contains("session"))
    return internal_error("session not finished: " + s.dump());
  return std::filesystem::path(s["session"].get<std::string>());
}

// The same from YAML texts of a rig config and a plan (their names in errors: rig.yaml, plan.yaml).
inline Result<std::filesystem::path> record_simulated_session(
    const std::string& rig_yaml, const std::string& plan_yaml,
    const std::filesystem::path& sessions_dir, int timeout_ms = 1'800'000) {
  HC_ASSIGN_OR_RETURN(rig::RigConfig cfg, rig::parse_rig_config(rig_yaml, "rig.yaml"));
  HC_ASSIGN_OR_RETURN(rig::Plan plan, rig::parse_plan(plan_yaml, "plan.yaml"));
  return record_simulated_session(std::move(cfg), plan, sessions_dir, timeout_ms);
}

// The same, recorded once per test binary build and reused by the binary's later processes:
// ctest runs every test of a suite in its own process, so a suite whose SetUpTestSuite records a
// session recorded it once per test. The copy lives in the build's test-artifacts/session-cache,
// keyed by the two texts and the test executable's size and modification time (a rebuilt binary,
// whose recorder may differ, records afresh). Only for tests that read the session.
inline Result<std::filesystem::path> record_simulated_session_cached(
    const std::string& rig_yaml, const std::string& plan_yaml,
    const std::filesystem::path& sessions_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  std::string identity = rig_yaml + "\n---\n" + plan_yaml;
  if (!ec) {
    identity += "\n" + exe.string() + " " + std::to_string(fs::file_size(exe, ec)) + " " +
                std::to_string(fs::last_write_time(exe, ec).time_since_epoch().count());
  }
  const fs::path cache = fs::path(HARDCOPY_BIN_DIR) / ".." / "test-artifacts" / "session-cache";
  const fs::path cached =
      cache / (std::to_string(std::hash<std::string>{}(identity)) + ".mcap");
  if (!ec && fs::is_regular_file(cached, ec)) return cached;
  HC_ASSIGN_OR_RETURN(fs::path recorded,
                      record_simulated_session(rig_yaml, plan_yaml, sessions_dir));
  // Copied under a temporary name and renamed: a concurrent process sees all of it or nothing.
  fs::create_directories(cache, ec);
  const fs::path tmp = cache / (cached.filename().string() + ".tmp-" + std::to_string(::getpid()));
  if (fs::copy_file(recorded, tmp, fs::copy_options::overwrite_existing, ec)) {
    fs::rename(tmp, cached, ec);
    if (ec) fs::remove(tmp, ec);
  }
  return recorded;
}

// The simulated cameras' true calibration from a session's "sim_cameras" metadata, in the frame
// of its first camera (by name), as calibrate_rig reports a rig.
inline Result<RigCalibration> true_rig_of_session(const std::filesystem::path& session) {
  HC_ASSIGN_OR_RETURN(recording::McapReader reader, recording::McapReader::open(session));
  HC_ASSIGN_OR_RETURN(std::vector<recording::Metadata> md, reader.read_metadata());
  for (const recording::Metadata& m : md) {
    if (m.name != session::kMetadataSimCameras) continue;
    HC_ASSIGN_OR_RETURN(Json j, parse_json(m.metadata.at("json"), "sim_cameras"));
    RigCalibration rig;
    Eigen::Isometry3d cam0_from_world = Eigen::Isometry3d::Identity();
    for (const auto& [name, c] : j.items()) {  // names in order: cam0, cam1, ...
      HC_ASSIGN_OR_RETURN(CameraModel cm, camera_from_json(c, name, "sim_cameras." + name));
      const Eigen::Isometry3d cam_from_world = cm.camera_from_reference();
      if (rig.cameras.empty()) cam0_from_world = cam_from_world;
      const Eigen::Isometry3d cam_from_rig = cam_from_world * cam0_from_world.inverse();
      cm.R = cam_from_rig.linear();
      cm.t_m = cam_from_rig.translation();
      rig.cameras.push_back(cm);
    }
    return rig;
  }
  return not_found(session.string() + ": no sim_cameras metadata");
}

}  // namespace hc::testing
