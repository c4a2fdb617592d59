// The "sim" backends: every device kind on the shared simulated world (sim_world.h), one kind per
// file (sim_camera.cpp, sim_trigger.cpp, sim_fsr.cpp, sim_force_torque.cpp, sim_arm.cpp).
#include "rig_daemon/simulation/sim_backends.h"
#include "sim_devices_internal.h"

namespace hc::devices {

Status register_sim_backends(BackendRegistry& registry, std::shared_ptr<sim::World> world) {
  if (!world) return invalid_argument("the 'sim' backends need a simulated world");
  HC_RETURN_IF_ERROR(registry.add<Camera>("sim", sim_backend::camera_factory(world),
                                          "camera rendering the simulated specimen's markers"));
  HC_RETURN_IF_ERROR(
      registry.add<Trigger>("sim", sim_backend::trigger_factory(world), "simulated trigger lines"));
  HC_RETURN_IF_ERROR(registry.add<Fsr>("sim", sim_backend::fsr_factory(world),
                                       "simulated FSR (power-law response)"));
  HC_RETURN_IF_ERROR(registry.add<ForceTorque>("sim", sim_backend::force_torque_factory(world),
                                               "simulated 6-axis force-torque sensor"));
  HC_RETURN_IF_ERROR(registry.add<Arm>("sim", sim_backend::arm_factory(world),
                                       "simulated 4-DOF arm with the probe"));
  return {};
}

SimulatedBoardInput sim::board_input(std::shared_ptr<World> world) {
  SimulatedBoardInput input;
  input.force_n = [world](std::int64_t t_ns) { return world->true_force_n(t_ns); };
  input.seed = [world](const std::string& key) { return world->device_seed(key); };
  return input;
}

}  // namespace hc::devices
