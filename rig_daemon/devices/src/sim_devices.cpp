// The "sim" backends: every device kind on the shared simulated world (sim_world.h), one kind per
// file (sim_camera.cpp, sim_trigger.cpp, sim_fsr.cpp, sim_force_torque.cpp, sim_arm.cpp).
#include "rig_daemon/devices/registry.h"
#include "sim_devices_internal.h"

namespace hc::devices {

Status register_sim_backends(BackendRegistry& registry) {
  HC_RETURN_IF_ERROR(registry.add<Camera>("sim", sim_backend::camera_factory(),
                                          "camera rendering the simulated specimen's markers"));
  HC_RETURN_IF_ERROR(
      registry.add<Trigger>("sim", sim_backend::trigger_factory(), "simulated trigger lines"));
  HC_RETURN_IF_ERROR(
      registry.add<Fsr>("sim", sim_backend::fsr_factory(), "simulated FSR (power-law response)"));
  HC_RETURN_IF_ERROR(registry.add<ForceTorque>("sim", sim_backend::force_torque_factory(),
                                               "simulated 6-axis force-torque sensor"));
  HC_RETURN_IF_ERROR(
      registry.add<Arm>("sim", sim_backend::arm_factory(), "simulated 4-DOF arm with the probe"));
  return {};
}

}  // namespace hc::devices
