// libcamera enumeration (the "libcamera" camera backend itself is registered by
// register_hardware_backends()).
#pragma once

#include <string>
#include <vector>

#include "common/status.h"

namespace hc::rig {

// The ids of the cameras libcamera's CameraManager sees (empty when there are none).
// kUnavailable when the camera manager cannot start.
Result<std::vector<std::string>> list_libcamera_cameras();

}  // namespace hc::rig
