// Trigger outputs: libgpiod lines, the trigger firmware, simulated lines, replayed edges. A trigger
// fires pulse trains on its configured lines and reports every edge it fired with its time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices {

class Trigger : public Device {
 public:
  static constexpr DeviceKind kKind = DeviceKind::kTrigger;
  using Device::Device;
  DeviceKind kind() const final { return kKind; }

  // Starts a pulse train (kActive). kFailedPrecondition if one is already running;
  // kInvalidArgument for a rate <= 0 or a width not in (0, 1/rate).
  Status start(const PulseTrain& train);
  // Stops the running pulse train (no-op if none). Edges already fired stay readable.
  Status stop();
  // Fires one pulse now (kActive, no pulse train running).
  Status fire();
  // True while a pulse train runs (count not reached, not stopped).
  virtual bool running() const = 0;
  // Appends fired edges in time order (rising edges; falling edges too when the backend is
  // configured with `report_falling: true`).
  Result<std::size_t> read(std::vector<TriggerEdge>& out, Duration timeout);
  // The output lines every pulse drives (valid after configure()).
  virtual std::vector<std::uint32_t> lines() const = 0;

 protected:
  virtual Status on_start(const PulseTrain& train) = 0;
  virtual Status on_stop() = 0;
  virtual Status on_fire() = 0;
  virtual Result<std::size_t> on_read(std::vector<TriggerEdge>& out, Duration timeout) = 0;
};

// OK, or kInvalidArgument naming what is wrong with `train`.
Status validate(const PulseTrain& train);

}  // namespace hc::devices
