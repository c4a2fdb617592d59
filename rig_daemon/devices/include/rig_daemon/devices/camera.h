// Cameras: Aravis (GigE Vision), V4L2, libcamera, simulated (renders the virtual specimen's
// markers), replayed. See device.h for the lifecycle and the read() contract.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices {

enum class TriggerMode : std::uint8_t {
  kFreeRun,   // the camera runs at frame_rate_hz by itself
  kSoftware,  // one frame per software_trigger()
  kHardware,  // one frame per rising edge on the camera's trigger input
};
// "free_run", "software", "hardware" (the `trigger` values of a camera's config).
std::string_view to_string(TriggerMode mode);
std::optional<TriggerMode> trigger_mode_from_string(std::string_view name);

// The stream a configured camera will deliver.
struct CameraInfo {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  PixelFormat format = PixelFormat::kMono8;
  TriggerMode trigger_mode = TriggerMode::kHardware;
  double frame_rate_hz = 0.0;  // free-run rate; the expected maximum rate otherwise
  double exposure_s = 0.0;
};

class Camera : public Device {
 public:
  static constexpr DeviceKind kKind = DeviceKind::kCamera;
  using Device::Device;
  DeviceKind kind() const final { return kKind; }

  // Appends completed frames (see device.h); counts them as received. Lost frames (frame id gaps)
  // are counted by the backend.
  Result<std::size_t> read(std::vector<Frame>& out, Duration timeout);
  // Asks for one frame now (kSoftware mode; kActive). kUnsupported if the backend cannot.
  Status software_trigger();
  // Valid after configure().
  virtual CameraInfo camera_info() const = 0;

 protected:
  virtual Result<std::size_t> on_read(std::vector<Frame>& out, Duration timeout) = 0;
  virtual Status on_software_trigger();
};

}  // namespace hc::devices
