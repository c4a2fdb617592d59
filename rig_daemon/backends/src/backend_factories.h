// Factories of the backends registered by register_hardware_backends() (private to the library).
#pragma once

#include <memory>

#include "common/status.h"
#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/fsr.h"
#include "rig_daemon/devices/trigger.h"

namespace hc::rig {

Result<std::unique_ptr<devices::ForceTorque>> make_netft_force_torque(
    const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Arm>> make_modbus_arm(const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Camera>> make_aravis_camera(const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Camera>> make_v4l2_camera(const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Camera>> make_libcamera_camera(const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Trigger>> make_gpiod_trigger(const devices::DeviceContext& ctx);
Result<std::unique_ptr<devices::Fsr>> make_phidget_fsr(const devices::DeviceContext& ctx);

}  // namespace hc::rig
