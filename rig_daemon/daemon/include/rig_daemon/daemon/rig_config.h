// The rig config: which backend drives each device, the safety limits the daemon enforces, and
// where sessions go. YAML through common/config.h ("FILE:LINE: key: expected ...").
//
//   devices:                       # name -> kind + backend (registered by name) + the backend's
//     cam0: {kind: camera, backend: sim, width: 320}   # own keys (checked by its configure())
//     trigger: {kind: trigger, backend: sim}
//     fsr: {kind: fsr, backend: sim}
//     ft: {kind: force_torque, backend: sim}
//     arm: {kind: arm, backend: sim}
//   workspace: {min_m: [-0.1, -0.1, 0.0], max_m: [0.1, 0.1, 0.2]}
//   max_force_n: 50                # no plan may ask for more (checked when it is started)
//   start_max_force_n: 2           # an automated capture refuses to start above this force
//   sessions_dir: ./sessions
//   socket: ./sessions/rigd.sock   # optional; see default_socket_path()
//   control_period_s: 0.001        # safety / arm control cycle
//   stall_timeout_s: 0.05          # no F/T sample for this long while the arm moves -> stop
//   compression: zstd              # zstd | lz4 | none
//   seed: 1                        # seed of the simulated world
//   http: {listen: "127.0.0.1:7878", allow_remote: false, enabled: true}   # the live page
//   world: {...}                   # options of the simulated world (simulation/sim_world.h)
//
// `rigd` with no arguments uses kEmbeddedDefaultRigConfig (everything "sim").
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"
#include "common/json.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/devices/device.h"

namespace hc::rig {

using devices::DeviceKind;

// One entry of `devices:`. The backend's own keys stay in the document (RigConfig::document) and
// are read by the device's configure() when the daemon creates it.
struct DeviceConfig {
  std::string name;  // the key in `devices:`
  DeviceKind kind = DeviceKind::kCamera;
  std::string backend = "sim";
  Status read(ConfigNode node);
};

// The live page (http_server.h): where it listens; other machines may reach it only with
// allow_remote (it is bound to loopback otherwise).
struct HttpConfig {
  bool enabled = true;
  std::string listen = "127.0.0.1:7878";
  bool allow_remote = false;
  Status read(ConfigNode node);
};

struct RigConfig {
  std::vector<DeviceConfig> devices;  // in file order
  WorkspaceBox workspace;
  double max_force_n = 50.0;
  double start_max_force_n = 2.0;
  std::filesystem::path sessions_dir = "sessions";
  std::filesystem::path socket;  // empty: default_socket_path()
  double control_period_s = 0.001;
  double stall_timeout_s = 0.05;
  std::string compression = "zstd";
  std::uint64_t seed = 1;
  HttpConfig http;
  std::string source_text;                 // the YAML as read (recorded in each session's metadata)
  std::string source_name;                 // file name, or "<embedded default>"
  std::shared_ptr<const Config> document;  // the parsed YAML (for the devices' configure())

  Status read(ConfigNode node);
  const DeviceConfig* find(std::string_view name) const;
  // The first device of `kind`, or nullptr.
  const DeviceConfig* first(DeviceKind kind) const;
  Json to_json() const;
};

// All devices simulated (3 hand-held cameras + 7 arm cameras share names cam0..cam6), sessions
// under ./sessions/.
extern const std::string_view kEmbeddedDefaultRigConfig;

Result<RigConfig> parse_rig_config(std::string_view text, std::string_view name);
Result<RigConfig> load_rig_config(const std::filesystem::path& path);
Result<RigConfig> embedded_default_rig_config();

// The control socket: config.socket if set; else sessions_dir/rigd.sock (./sessions/rigd.sock in
// the embedded default), or $XDG_RUNTIME_DIR/hardcopy-rigd.sock when that path is too long for a
// Unix socket.
std::filesystem::path default_socket_path(const RigConfig& config);

}  // namespace hc::rig
