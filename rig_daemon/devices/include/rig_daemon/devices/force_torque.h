// Six-axis force-torque sensors: ATI Net F/T (RDT over UDP), simulated, replayed.
#pragma once

#include <cstddef>
#include <vector>

#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices {

class ForceTorque : public Device {
 public:
  static constexpr DeviceKind kKind = DeviceKind::kForceTorque;
  using Device::Device;
  DeviceKind kind() const final { return kKind; }

  // Appends samples in order (see device.h); gaps in the sensor's sequence are counted as lost.
  Result<std::size_t> read(std::vector<WrenchSample>& out, Duration timeout);
  // Tare: from the next sample on, SI values are relative to the current reading (kActive).
  Status bias();
  // Removes the bias (kInactive or kActive).
  Status clear_bias();
  // Valid after configure().
  virtual WrenchCalibration calibration() const = 0;
  virtual double sample_rate_hz() const = 0;

 protected:
  virtual Result<std::size_t> on_read(std::vector<WrenchSample>& out, Duration timeout) = 0;
  virtual Status on_bias() = 0;
  virtual Status on_clear_bias() = 0;
};

}  // namespace hc::devices
