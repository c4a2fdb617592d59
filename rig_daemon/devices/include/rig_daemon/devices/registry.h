// Backends registered by name per device kind (after libcamera's pipeline handlers and
// ros2_control's plugins); the rig config names the backend of every device:
//
//   devices:
//     cam0: {kind: camera, backend: aravis, ...}   # the rest of the map goes to configure()
//     ft:   {kind: force_torque, backend: sim}
//
// Registration is explicit (each backend library exports a register_*_backends(BackendRegistry&)
// function the daemon calls), not by static initialisers, because the linker drops unreferenced
// objects of static libraries and with them their initialisers.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/status.h"
#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/fsr.h"
#include "rig_daemon/devices/trigger.h"

namespace hc::devices {

// Makes an unconfigured device of kind D from the context (name, backend, clock). What else a
// backend needs (the simulated world, a recorded session) its factory holds from registration.
template <typename D>
using DeviceFactory = std::function<Result<std::unique_ptr<D>>(const DeviceContext&)>;

class BackendRegistry {
 public:
  // Registers `factory` as backend `backend` of D's kind (D is Camera, Trigger, Fsr, ForceTorque
  // or Arm). kInvalidArgument if that kind already has a backend of that name.
  template <typename D>
  Status add(std::string backend, DeviceFactory<D> factory, std::string description = {}) {
    AnyFactory any =
        [f = std::move(factory)](const DeviceContext& ctx) -> Result<std::unique_ptr<Device>> {
      Result<std::unique_ptr<D>> made = f(ctx);
      if (!made.ok()) return made.status();
      return std::unique_ptr<Device>(std::move(made).value());
    };
    return add_any(D::kKind, std::move(backend), std::move(any), std::move(description));
  }

  // Makes a device of kind D with backend ctx.backend. kNotFound (listing the known backends) for
  // an unknown backend.
  template <typename D>
  Result<std::unique_ptr<D>> create(const DeviceContext& ctx) const {
    Result<std::unique_ptr<Device>> made = create(D::kKind, ctx);
    if (!made.ok()) return made.status();
    // The factory registered under D::kKind made a D (add<D> wrapped it).
    return std::unique_ptr<D>(static_cast<D*>(std::move(made).value().release()));
  }
  Result<std::unique_ptr<Device>> create(DeviceKind kind, const DeviceContext& ctx) const;

  bool has(DeviceKind kind, std::string_view backend) const;
  // Backend names of `kind`, sorted.
  std::vector<std::string> backends(DeviceKind kind) const;
  // The description given at registration ("" if none or unknown).
  std::string description(DeviceKind kind, std::string_view backend) const;

 private:
  using AnyFactory = std::function<Result<std::unique_ptr<Device>>(const DeviceContext&)>;
  struct Entry {
    AnyFactory factory;
    std::string description;
  };
  Status add_any(DeviceKind kind, std::string backend, AnyFactory factory, std::string description);
  std::map<std::pair<DeviceKind, std::string>, Entry, std::less<>> entries_;
};

// Backends of this library: "firmware" for trigger and FSR (the trigger/FSR firmware through
// firmware_host's host driver). The simulated board's ADC measures `input.force_n` when given (the
// simulated world's probe force: rig_daemon/simulation/sim_backends.h), else nothing.
// Elsewhere: "sim" (rig_daemon/simulation/sim_backends.h), "replay" (rig_daemon/replay/replay.h)
// and the hardware backends (rig_daemon/backends/hardware_backends.h).
struct SimulatedBoardInput {
  std::function<double(std::int64_t host_ns)> force_n;        // probe force (N) at a host time
  std::function<std::uint64_t(const std::string& key)> seed;  // per-device seeds
};
Status register_firmware_backends(BackendRegistry& registry, SimulatedBoardInput input = {});

}  // namespace hc::devices
