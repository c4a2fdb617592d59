// The real-hardware device backends of hardcopy_backends, registered by name in the devices
// registry (rig_daemon/devices/registry.h). The rig config picks them per device:
//
//   devices:
//     ft:   {kind: force_torque, backend: netft, host: 192.168.1.1, calibration_source: sensor}
//     arm:  {kind: arm, backend: modbus, transport: tcp, host: 192.168.1.2, port: 502}
//     cam0: {kind: camera, backend: aravis, address: 192.168.1.10, trigger: hardware}
//     cam1: {kind: camera, backend: v4l2, device: /dev/video0}
//     cam2: {kind: camera, backend: libcamera, camera_id: "..."}
//     trig: {kind: trigger, backend: gpiod, chip: gpiochip0, lines: [17, 27]}
//     fsr:  {kind: fsr, backend: phidget, sensor: 0}
//
// Each backend's configuration keys are listed with its register line in hardware_backends.cpp
// and in the option structs of the client headers (netft_client.h, modbus_arm_client.h,
// aravis_camera.h, ...). Real backends stamp host_ns on CLOCK_MONOTONIC (the devices'
// MonotonicClock); with a simulated clock they stamp clock().now_ns() at reception instead.
#pragma once

#include "common/status.h"
#include "rig_daemon/devices/registry.h"

namespace hc::rig {

// Registers "netft" (force_torque), "modbus" (arm), "aravis", "v4l2", "libcamera" (camera),
// "gpiod" (trigger) and "phidget" (fsr). Fails if a name is already taken.
Status register_hardware_backends(devices::BackendRegistry& registry);

}  // namespace hc::rig
