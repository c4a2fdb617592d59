// Force-sensing resistors: the trigger/FSR firmware's ADC, a Phidget InterfaceKit 8/8/8, simulated,
// replayed. Raw readings are always delivered with the calibration that maps them to newtons.
#pragma once

#include <cstddef>
#include <vector>

#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices {

class Fsr : public Device {
 public:
  static constexpr DeviceKind kKind = DeviceKind::kFsr;
  using Device::Device;
  DeviceKind kind() const final { return kKind; }

  // Appends samples in order (see device.h). Gaps in FsrSample::sequence are counted as lost.
  Result<std::size_t> read(std::vector<FsrSample>& out, Duration timeout);
  // Valid after configure() (from the config's `calibration` map or the backend's default).
  virtual FsrCalibration calibration() const = 0;
  // Nominal samples per second (for triggered sampling: the expected trigger rate; 0 if unknown).
  virtual double sample_rate_hz() const = 0;

 protected:
  virtual Result<std::size_t> on_read(std::vector<FsrSample>& out, Duration timeout) = 0;
  // Reads the config's optional `calibration` map {full_scale, threshold, scale_n, exponent} over
  // *calibration (keys left out keep their values); errors are collected in `node`.
  static void read_calibration(ConfigNode& node, FsrCalibration* calibration);
};

}  // namespace hc::devices
