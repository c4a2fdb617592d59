#include "rig_daemon/daemon/rig_config.h"

#include <cstdlib>
#include <set>

#include "common/file_io.h"

namespace hc::rig {

Status DeviceConfig::read(ConfigNode node) {
  std::string kind_name;
  if (node.required("kind", kind_name, {"camera", "trigger", "fsr", "force_torque", "arm"}))
    kind = *devices::device_kind_from_string(kind_name);
  node.required("backend", backend);
  if (node.status().ok() && backend.empty()) node.error("backend", "expected a backend name");
  node.allow_unknown_keys();  // the backend's configure() checks the rest
  return node.status();
}

Status RigConfig::read(ConfigNode node) {
  if (std::optional<ConfigNode> devs = node.find("devices")) {
    if (auto items = devs->entries()) {
      for (auto& [key, child] : *items) {
        DeviceConfig d;
        d.name = key;
        if (child.get(d)) devices.push_back(std::move(d));
      }
      if (items->empty()) devs->error("expected at least one device");
    }
  } else {
    node.error("devices", "expected a map of devices (name: {kind: ..., backend: ..., ...})");
  }
  node.required("workspace", workspace);
  // The simulated world's options (sim::WorldOptions) are read when the rig is built.
  if (std::optional<ConfigNode> w = node.find("world")) w->allow_unknown_keys();
  node.optional("max_force_n", max_force_n, Bounds{0.0, kMaxPlanForceN, true, false});
  node.optional("start_max_force_n", start_max_force_n, Bounds{0.0, kMaxPlanForceN, true, false});
  std::string dir;
  if (node.optional("sessions_dir", dir)) {
    if (dir.empty()) node.error("sessions_dir", "expected a directory");
    sessions_dir = dir;
  }
  std::string sock;
  if (node.optional("socket", sock)) {
    // sockaddr_un::sun_path holds 108 bytes including the terminating NUL.
    if (sock.empty() || sock.size() > 107)
      node.error("socket", "expected a path of 1-107 bytes (the Unix socket limit)");
    socket = sock;
  }
  // The control cycle must be fast enough for the over-force stop (tens of ms would let a soft
  // specimen be crushed) and not so fast that it starves a 2-core machine.
  node.optional("control_period_s", control_period_s, Bounds::between(1e-4, 0.05));
  node.optional("stall_timeout_s", stall_timeout_s, Bounds::between(1e-3, 5.0));
  node.optional("compression", compression, {"zstd", "lz4", "none"});
  node.optional("seed", seed);
  if (node.status().ok()) {
    if (stall_timeout_s < control_period_s)
      node.error("stall_timeout_s", "must be at least control_period_s");
    if (start_max_force_n >= max_force_n)
      node.error("start_max_force_n",
                 "must be below max_force_n (" + std::to_string(max_force_n) + " N)");
  }
  return node.status();
}

const DeviceConfig* RigConfig::find(std::string_view name) const {
  for (const DeviceConfig& d : devices)
    if (d.name == name) return &d;
  return nullptr;
}

const DeviceConfig* RigConfig::first(DeviceKind kind) const {
  for (const DeviceConfig& d : devices)
    if (d.kind == kind) return &d;
  return nullptr;
}

Json RigConfig::to_json() const {
  Json devs = Json::array();
  for (const DeviceConfig& d : devices) {
    devs.push_back(
        {{"name", d.name}, {"kind", devices::to_string(d.kind)}, {"backend", d.backend}});
  }
  return Json{{"source", source_name},
              {"devices", devs},
              {"workspace", workspace.to_json()},
              {"max_force_n", max_force_n},
              {"start_max_force_n", start_max_force_n},
              {"sessions_dir", sessions_dir.string()},
              {"socket", default_socket_path(*this).string()},
              {"control_period_s", control_period_s},
              {"stall_timeout_s", stall_timeout_s},
              {"compression", compression},
              {"seed", seed}};
}

const std::string_view kEmbeddedDefaultRigConfig =
    R"(# rigd's embedded default: every device simulated. Seven 320x240 cameras on a half circle
# 0.3 m around the specimen (thesis 5.6); the first three serve the hand-held protocol (4.4).
devices:
  cam0: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [0.3000, 0.0000, 0.3], look_at_m: [0, 0, 0.05]}
  cam1: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [0.2598, -0.1500, 0.3], look_at_m: [0, 0, 0.05]}
  cam2: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [0.1500, -0.2598, 0.3], look_at_m: [0, 0, 0.05]}
  cam3: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [0.0000, -0.3000, 0.3], look_at_m: [0, 0, 0.05]}
  cam4: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [-0.1500, -0.2598, 0.3], look_at_m: [0, 0, 0.05]}
  cam5: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [-0.2598, -0.1500, 0.3], look_at_m: [0, 0, 0.05]}
  cam6: {kind: camera, backend: sim, width: 320, height: 240, fx: 400, fy: 400,
         position_m: [-0.3000, 0.0000, 0.3], look_at_m: [0, 0, 0.05]}
  trigger: {kind: trigger, backend: sim}
  fsr: {kind: fsr, backend: sim, sampling: triggered}  # read on every trigger edge (thesis 4.4)
  ft: {kind: force_torque, backend: sim}
  arm: {kind: arm, backend: sim}
workspace: {min_m: [-0.1, -0.1, 0.0], max_m: [0.1, 0.1, 0.2]}
max_force_n: 50
sessions_dir: ./sessions
control_period_s: 0.001
stall_timeout_s: 0.05
compression: zstd
seed: 1
)";

Result<RigConfig> parse_rig_config(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(Config config, parse_config(text, name));
  HC_ASSIGN_OR_RETURN(RigConfig rig, read_config<RigConfig>(config));
  rig.source_text = std::string(text);
  rig.source_name = std::string(name);
  rig.document = std::make_shared<const Config>(std::move(config));
  return rig;
}

Result<RigConfig> load_rig_config(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, kMaxConfigBytes));
  return parse_rig_config(text, path.string());
}

Result<RigConfig> embedded_default_rig_config() {
  return parse_rig_config(kEmbeddedDefaultRigConfig, "<embedded default>");
}

std::filesystem::path default_socket_path(const RigConfig& config) {
  if (!config.socket.empty()) return config.socket;
  std::filesystem::path path = config.sessions_dir / "rigd.sock";
  // sockaddr_un::sun_path holds 107 bytes plus NUL: a deep sessions dir falls back to the
  // per-user runtime dir.
  if (path.string().size() > 107) {
    if (const char* xdg = std::getenv("XDG_RUNTIME_DIR"); xdg != nullptr && *xdg != '\0')
      return std::filesystem::path(xdg) / "hardcopy-rigd.sock";
  }
  return path;
}

}  // namespace hc::rig
