// Simulated sessions for the tracking tests: a high-resolution 7-camera rig (1600 x 1200, thesis
// Sec. 5.6) recorded in-process with simulated time, its TRUE calibration (from the rig config
// through read_camera, as the simulator reads it) and a template tet mesh whose top nodes are the
// specimen's marker grid.
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "camera/camera_model.h"
#include "common/config.h"
#include "common/tet_mesh_io.h"
#include "processing/fem/verification.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"
#include "rig_daemon/simulation/sim_dots.h"
#include "sim_session.h"

namespace hc::tracking::testing {

// Seven cameras on a half circle of radius 0.3 m, 0.25 m above the specimen's top (z = 0.05), as
// rig_sim.yaml but 1600 x 1200 with f = 7000 px (the 60 mm block spans ~1100 px; a 3 mm grid step
// is ~55 px and a 0.6 mm dot ~11 px in radius), mild distortion and 2 grey levels of pixel noise.
inline std::string hires_rig_yaml(const std::string& extra_camera_keys = "") {
  std::string devices;
  for (int i = 0; i < 7; ++i) {
    const double a = M_PI * i / 6.0;
    devices += fmt::format(
        "  cam{}: {{kind: camera, backend: sim, width: 1600, height: 1200, fx: 7000, fy: 7000,\n"
        "         distortion: [-0.05, 0.02, 0.0005, -0.0003, 0.0], pixel_noise: 2,\n"
        "         position_m: [{:.4f}, {:.4f}, 0.3], look_at_m: [0, 0, 0.05]{}}}\n",
        i, 0.3 * std::cos(a), -0.3 * std::sin(a), extra_camera_keys);
  }
  return "devices:\n" + devices +
         "  trigger: {kind: trigger, backend: sim}\n"
         "  fsr: {kind: fsr, backend: sim, sampling: triggered}\n"
         "  ft: {kind: force_torque, backend: sim}\n"
         "  arm: {kind: arm, backend: sim}\n"
         "workspace: {min_m: [-0.1, -0.1, 0.0], max_m: [0.1, 0.1, 0.2]}\n"
         "max_force_n: 50\ncontrol_period_s: 0.001\nstall_timeout_s: 0.05\n"
         "compression: zstd\nseed: 3\n"
         // The probe's shaft markers 15 and 35 mm above the tip: both inside every camera's view
         // (the simulator's default 60 / 110 mm are above these narrow views).
         "world: {probe: {marker_distances_m: [0.015, 0.035]}}\n";
}

// A press of `steps` steps (plans allow 30-200, thesis 5.6) up to `force_n` at (x, y) = `at`.
inline std::string press_plan_yaml(int steps, double force_n, double x = 0.0, double y = 0.0) {
  return fmt::format(
      "protocol: automated\nname: track_test\n"
      "locations:\n  - {{position_m: [{}, {}, 0.062], direction: [0, 0, -1]}}\n"
      "force_levels_n: [{}]\nsteps: {}\nsettle_s: 0.01\nmax_force_n: 45\nstep_m: 0.0005\n"
      "max_depth_m: 0.03\nworkspace: {{min_m: [-0.05, -0.05, 0.0], max_m: [0.05, 0.05, 0.12]}}\n"
      "cameras: [cam0, cam1, cam2, cam3, cam4, cam5, cam6]\nforce_torque: ft\narm: arm\n"
      "trigger_device: trigger\ntrigger: {{rate_hz: 100, pulse_width_s: 0.001}}\n",
      x, y, force_n, steps);
}

// Records a session; returns its path.
inline Result<std::filesystem::path> record_session(const std::filesystem::path& dir,
                                                    const std::string& rig_yaml,
                                                    const std::string& plan_yaml) {
  return hc::testing::record_simulated_session(rig_yaml, plan_yaml, dir);
}

// The true calibration of the rig config's cameras (world frame = rig frame).
inline Result<RigCalibration> true_calibration(const std::string& rig_yaml) {
  RigCalibration rig;
  HC_ASSIGN_OR_RETURN(Config cfg, parse_config(rig_yaml, "rig.yaml"));
  Status st = read_config(cfg, [&](ConfigNode root) -> Status {
    root.allow_unknown_keys();
    std::optional<ConfigNode> devs = root.find("devices");
    if (!devs) return invalid_argument("no devices");
    auto entries = devs->entries();
    if (!entries) return invalid_argument("devices is not a map");
    for (auto& [name, node] : *entries) {
      node.allow_unknown_keys();
      std::string kind;
      node.optional("kind", kind);
      if (kind != "camera") continue;
      CameraModel c = devices::sim::default_camera();
      HC_RETURN_IF_ERROR(read_camera(node, c));
      c.name = name;
      rig.cameras.push_back(c);
    }
    return {};
  });
  HC_RETURN_IF_ERROR(st);
  return rig;
}

// The specimen's template: a structured tet box over the 60 x 60 mm footprint with nodes on the
// 3 mm marker grid (specimen.h marker_grid: centred, both edges) and the top at z = 0.05 m.
inline TetMesh block_template() {
  std::vector<double> xs;
  for (int i = 0; i <= 20; ++i) xs.push_back(-0.03 + 0.003 * i);
  return fem::structured_box_mesh(xs, xs, {0.02, 0.035, 0.05});
}

}  // namespace hc::tracking::testing
