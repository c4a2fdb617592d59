// The "sim" backends: every device kind on one shared simulated world (sim_world.h). Their
// factories hold the world; a device cannot tell it apart from any other backend's.
#pragma once

#include <memory>

#include "rig_daemon/devices/registry.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::devices {

// Registers "sim" for every device kind on `world`. kInvalidArgument if `world` is null or a kind
// already has a "sim" backend.
Status register_sim_backends(BackendRegistry& registry, std::shared_ptr<sim::World> world);

namespace sim {
// What the firmware backends' simulated board measures on this world: its probe force and its
// per-device seeds (register_firmware_backends).
SimulatedBoardInput board_input(std::shared_ptr<World> world);
}  // namespace sim

}  // namespace hc::devices
