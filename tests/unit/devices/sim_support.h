// Helpers for the device tests: a deterministic simulated world and devices made through the
// registry, configured from YAML.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "rig_daemon/devices/registry.h"
#include "rig_daemon/replay/replay.h"
#include "rig_daemon/simulation/sim_backends.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::devices::testing {

struct SimRig {
  explicit SimRig(std::uint64_t seed = 7, sim::WorldOptions options = {}) {
    options.seed = seed;
    clock = std::make_shared<SimulatedClock>(1'000'000'000);
    world = std::make_shared<sim::World>(options, clock);
    EXPECT_TRUE(register_sim_backends(registry, world).ok());
    EXPECT_TRUE(register_firmware_backends(registry, sim::board_input(world)).ok());
  }
  DeviceContext context(const std::string& name, const std::string& backend = "sim") const {
    DeviceContext ctx;
    ctx.name = name;
    ctx.backend = backend;
    ctx.clock = clock;
    return ctx;
  }
  // A device of `kind` from `registry`; "replay" devices serve `replay` (set it first), through
  // a registry of their own since a replay backend holds its session from registration.
  Result<std::unique_ptr<Device>> create(DeviceKind kind, const DeviceContext& ctx) const {
    if (ctx.backend != "replay") return registry.create(kind, ctx);
    BackendRegistry replays;
    HC_RETURN_IF_ERROR(register_replay_backends(replays, replay));
    return replays.create(kind, ctx);
  }
  template <typename D>
  Result<std::unique_ptr<D>> create(const DeviceContext& ctx) const {
    Result<std::unique_ptr<Device>> made = create(D::kKind, ctx);
    if (!made.ok()) return made.status();
    return std::unique_ptr<D>(static_cast<D*>(std::move(made).value().release()));
  }
  // Backend "sim" unless the YAML names another with `backend: NAME` (read from the text).
  template <typename D>
  std::unique_ptr<D> make(const std::string& name, const std::string& yaml = "{}") {
    std::string backend = "sim";
    if (const std::size_t at = yaml.find("backend: "); at != std::string::npos)
      backend = yaml.substr(at + 9, yaml.find_first_of(",}", at) - at - 9);
    Result<std::unique_ptr<D>> made = create<D>(context(name, backend));
    EXPECT_TRUE(made.ok()) << made.status().to_string();
    if (!made.ok()) return nullptr;
    Status s = configure_from_yaml(**made, yaml, name);
    EXPECT_TRUE(s.ok()) << s.to_string();
    return std::move(made).value();
  }

  std::shared_ptr<SimulatedClock> clock;
  std::shared_ptr<ReplaySession> replay;  // for "replay" backends
  std::shared_ptr<sim::World> world;
  BackendRegistry registry;
};

}  // namespace hc::devices::testing
