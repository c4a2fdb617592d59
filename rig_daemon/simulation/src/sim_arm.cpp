// The "sim" arm: the world's 4-DOF arm carrying the probe.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_devices_internal.h"

namespace hc::devices::sim_backend {

namespace {

class SimArm final : public Arm {
 public:
  SimArm(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Arm(ctx), parts_(ctx, std::move(world)) {}

  ArmLimits limits() const override { return parts_.world().options().arm_limits; }

 protected:
  Status on_configure(ConfigNode node) override { return node.status(); }
  Status on_activate() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_deactivate() override {
    parts_.world().arm_stop(parts_.world().clock().now_ns());
    return {};
  }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_write(const ArmCommand& command) override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().arm_command(command, now);
  }
  Result<ArmState> on_read() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    ArmState s = parts_.world().arm_state(now);
    s.sequence = sequence_++;
    s.device_stamp_ns = parts_.device_stamp(now);
    return s;
  }
  Status on_stop() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    parts_.world().arm_stop(now);
    return {};
  }
  void describe(DeviceInfo& info) const override { info.model = "simulated 4-DOF arm"; }

 private:
  SimParts parts_;
  std::uint64_t sequence_ = 0;
};

}  // namespace

DeviceFactory<Arm> arm_factory(std::shared_ptr<World> world) {
  return sim_factory<Arm, SimArm>(std::move(world));
}

}  // namespace hc::devices::sim_backend
