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
  return {};
}

}  // namespace hc::rig
