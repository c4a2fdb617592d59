// The rig: every device of a rig config created through the backend registry, configured from
// its map in the config, sharing one clock and (for simulated devices) one simulated world; or,
// for a replay, every device stream of a recorded session.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/rig_config.h"
#include "rig_daemon/daemon/session_source.h"
#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "rig_daemon/devices/clock.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/fsr.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/devices/trigger.h"
#include "rig_daemon/replay/replay.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::rig {

class Rig {
 public:
  struct Options {
    RigConfig config;
    // Host time for every device; null: the host's monotonic clock. A SimulatedClock in
    // auto-advance mode runs a simulated rig as fast as the CPU allows, deterministically.
    std::shared_ptr<devices::Clock> clock;
    // Replay: the rig's devices are the session's recorded streams ("replay" backends, same
    // names and kinds); the config's devices are ignored, its limits and paths kept.
    std::shared_ptr<devices::ReplaySession> replay;
  };
  // Creates and configures every device (inactive). Errors name the device and the config key.
  static Result<std::unique_ptr<Rig>> create(Options options);
  ~Rig();

  const RigConfig& config() const { return config_; }
  devices::Clock& clock() const { return *clock_; }
  std::shared_ptr<devices::Clock> clock_ptr() const { return clock_; }
  // The simulated world, or null when no device is simulated.
  devices::sim::World* world() const { return world_.get(); }
  // A session's records besides the devices' (the simulated world's), or null when there are none.
  std::unique_ptr<SessionSource> make_session_source() const {
    return simulated_world_source(world_);
  }
  // The session being replayed, or null.
  devices::ReplaySession* replay() const { return replay_.get(); }

  devices::Device* find(std::string_view name) const;
  template <typename D>
  D* get(std::string_view name) const {
    devices::Device* d = find(name);
    return d != nullptr && d->kind() == D::kKind ? static_cast<D*>(d) : nullptr;
  }
  const std::vector<std::unique_ptr<devices::Device>>& devices() const { return devices_; }
  // `rigctl devices`: name, kind, backend, state, model, serial, details, stats, error.
  Json devices_json() const;

 private:
  Rig() = default;
  RigConfig config_;
  std::shared_ptr<devices::Clock> clock_;
  std::shared_ptr<devices::sim::World> world_;
  std::shared_ptr<devices::ReplaySession> replay_;
  devices::BackendRegistry registry_;
  std::vector<std::unique_ptr<devices::Device>> devices_;
};

// Device stats as JSON (received, lost, late, incomplete, errors).
Json stats_json(const devices::DeviceStats& stats);

}  // namespace hc::rig
