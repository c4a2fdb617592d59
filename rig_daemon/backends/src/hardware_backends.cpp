#include "rig_daemon/backends/hardware_backends.h"

#include "backend_factories.h"

namespace hc::rig {

Status register_hardware_backends(devices::BackendRegistry& registry) {
  using namespace devices;
  HC_RETURN_IF_ERROR(registry.add<ForceTorque>("netft", make_netft_force_torque,
                                               "ATI Net F/T over RDT/UDP (netft_client.h)"));
  HC_RETURN_IF_ERROR(registry.add<Arm>("modbus", make_modbus_arm,
                                       "4-DOF arm over Modbus TCP/RTU (arm_register_map.h)"));
  HC_RETURN_IF_ERROR(
      registry.add<Camera>("aravis", make_aravis_camera, "GigE Vision camera through Aravis 0.8"));
  HC_RETURN_IF_ERROR(registry.add<Fsr>("phidget", make_phidget_fsr,
                                       "FSR on a Phidget InterfaceKit 8/8/8 over libusb"));
  HC_RETURN_IF_ERROR(registry.add<Camera>("v4l2", make_v4l2_camera,
                                          "Video4Linux2 capture device, mmap streaming"));
  HC_RETURN_IF_ERROR(
      registry.add<Trigger>("gpiod", make_gpiod_trigger, "GPIO output lines through libgpiod"));
  HC_RETURN_IF_ERROR(
      registry.add<Camera>("libcamera", make_libcamera_camera, "camera through libcamera"));
  return {};
}

}  // namespace hc::rig
