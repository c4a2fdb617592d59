// 4-DOF arms: Modbus TCP/RTU (libmodbus), simulated, replayed (states only; commands are refused).
// The daemon enforces the workspace and force limits itself; backends additionally refuse targets
// outside limits() with kInvalidArgument.
#pragma once

#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices {

class Arm : public Device {
 public:
  static constexpr DeviceKind kKind = DeviceKind::kArm;
  using Device::Device;
  DeviceKind kind() const final { return kKind; }

  // Sends a command (kActive). kStop is the same as stop(). A target outside limits() is
  // kInvalidArgument and the arm is not moved. Returns once the arm accepted the command (not when
  // the motion ends: poll read() for ArmMotion::kHolding).
  Status write(const ArmCommand& command);
  // Polls the arm's state (kActive); counts as one received item.
  Result<ArmState> read();
  // Stops motion immediately. Safe to call from any thread and in any state after configure();
  // never blocks longer than one bus transaction.
  Status stop();
  // Valid after configure().
  virtual ArmLimits limits() const = 0;

 protected:
  virtual Status on_write(const ArmCommand& command) = 0;
  virtual Result<ArmState> on_read() = 0;
  virtual Status on_stop() = 0;
};

}  // namespace hc::devices
