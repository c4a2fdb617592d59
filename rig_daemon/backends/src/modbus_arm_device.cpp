// Backend "modbus": the rig's 4-DOF arm controller over Modbus TCP/RTU (arm_register_map.h), as a
// devices::Arm.
//
// Config keys: those of ModbusArmOptions (transport, host, port, device, baud, parity, data_bits,
// stop_bits, slave_id, response_timeout_s, connect_timeout_s) plus the limits the backend refuses
// to leave (the daemon checks them too):
//   workspace_min_m, workspace_max_m  [x, y, z] of the tool tip (default +-0.2, +-0.2, 0..0.3)
//   yaw_min_rad, yaw_max_rad          (default +-pi)
//   max_speed_m_s                     (default 0.05)
// A link failure during read/write is retried once (the client reconnects); if the controller is
// still gone the device enters kError, and reset() succeeds once it answers again.
#include <array>
#include <cmath>
#include <numbers>

#include "backend_factories.h"
#include "rig_daemon/backends/modbus_arm_client.h"

namespace hc::rig {
namespace {

using devices::ArmCommand;
using devices::ArmMotion;
using devices::ArmState;

ArmMotion to_motion(arm::Motion m) {
  switch (m) {
    case arm::Motion::kIdle:
      return ArmMotion::kIdle;
    case arm::Motion::kHoming:
      return ArmMotion::kHoming;
    case arm::Motion::kMoving:
      return ArmMotion::kMoving;
    case arm::Motion::kHolding:
      return ArmMotion::kHolding;
    case arm::Motion::kStopped:
      return ArmMotion::kStopped;
    case arm::Motion::kFault:
      return ArmMotion::kFault;
  }
  return ArmMotion::kFault;
}

bool link_down(const Status& s) {
  return s.code() == StatusCode::kUnavailable || s.code() == StatusCode::kDeadlineExceeded;
}

class ModbusArm final : public devices::Arm {
 public:
  explicit ModbusArm(const devices::DeviceContext& ctx) : Arm(ctx) {}

  devices::ArmLimits limits() const override { return limits_; }

 protected:
  Status on_configure(ConfigNode node) override {
    ModbusArmOptions o;
    Status s = o.read(node);
    std::array<double, 3> lo{limits_.min.x_m, limits_.min.y_m, limits_.min.z_m};
    std::array<double, 3> hi{limits_.max.x_m, limits_.max.y_m, limits_.max.z_m};
    node.optional("workspace_min_m", lo);
    node.optional("workspace_max_m", hi);
    node.optional("yaw_min_rad", limits_.min.yaw_rad);
    node.optional("yaw_max_rad", limits_.max.yaw_rad);
    node.optional("max_speed_m_s", limits_.max_speed_m_s, Bounds::positive());
    HC_RETURN_IF_ERROR(node.status());
    HC_RETURN_IF_ERROR(s);
    HC_RETURN_IF_ERROR(o.validate());
    limits_.min = {lo[0], lo[1], lo[2], limits_.min.yaw_rad};
    limits_.max = {hi[0], hi[1], hi[2], limits_.max.yaw_rad};
    if (lo[0] >= hi[0] || lo[1] >= hi[1] || lo[2] >= hi[2] ||
        limits_.min.yaw_rad >= limits_.max.yaw_rad)
      return invalid_argument("workspace_min_m/workspace_max_m: every min must be below its max");
    HC_ASSIGN_OR_RETURN(client_, ModbusArmClient::create(o));
    return {};
  }

  Status on_activate() override {
    HC_RETURN_IF_ERROR(client_->connect());
    HC_ASSIGN_OR_RETURN(arm::StatusBlock st, client_->read_status());
    sequence16_ = st.ack_sequence;  // continue after whatever the controller saw last
    return {};
  }

  Status on_deactivate() override {
    client_->close();
    return {};
  }

  Status on_reset() override {
    // Succeeds only when the controller answers again.
    Status s = client_->connect();
    if (!s.ok()) return s.with_context("arm '" + name() + "'");
    client_->close();
    return {};
  }

  Status on_write(const ArmCommand& c) override {
    arm::CommandBlock b;
    switch (c.type) {
      case ArmCommand::Type::kHome:
        b.opcode = arm::Opcode::kHome;
        break;
      case ArmCommand::Type::kMoveTo:
        b.opcode = arm::Opcode::kMoveTo;
        b.x_m = c.target.x_m;
        b.y_m = c.target.y_m;
        b.z_m = c.target.z_m;
        b.yaw_rad = c.target.yaw_rad;
        b.speed_m_s = c.speed_m_s > 0 ? c.speed_m_s : 0.0;
        break;
      case ArmCommand::Type::kSetSpeed:
        b.opcode = arm::Opcode::kSetSpeed;
        b.speed_m_s = c.speed_m_s;
        break;
      case ArmCommand::Type::kStop:
        b.opcode = arm::Opcode::kStop;
        break;
      case ArmCommand::Type::kClearFault:
        b.opcode = arm::Opcode::kClearFault;
        break;
    }
    if ((c.type == ArmCommand::Type::kMoveTo || c.type == ArmCommand::Type::kSetSpeed) &&
        (c.speed_m_s > limits_.max_speed_m_s ||
         (c.type == ArmCommand::Type::kSetSpeed && !(c.speed_m_s > 0))))
      return invalid_argument("arm '" + name() + "': speed " + std::to_string(c.speed_m_s) +
                              " m/s outside (0, " + std::to_string(limits_.max_speed_m_s) + "]");
    b.sequence = static_cast<std::uint16_t>(sequence16_ + 1);
    Status s = client_->send(b);
    if (!s.ok() && link_down(s)) s = client_->send(b);  // once more, over a fresh connection
    if (!s.ok()) return s.with_context("arm '" + name() + "'");
    sequence16_ = b.sequence;
    sent_[b.sequence % sent_.size()] = {b.sequence, c.sequence};
    if (c.type == ArmCommand::Type::kMoveTo) target_ = c.target;
    if (c.type == ArmCommand::Type::kHome) homing_ = true;
    return {};
  }

  Result<ArmState> on_read() override {
    auto st = client_->read_status();
    if (!st.ok() && link_down(st.status())) {
      ++reconnects_;
      st = client_->read_status();
    }
    if (!st.ok()) return st.status().with_context("arm '" + name() + "'");
    const std::int64_t now = clock().now_ns();
    ArmState a;
    a.pose = {st->x_m, st->y_m, st->z_m, st->yaw_rad};
    if (homing_ && st->motion != arm::Motion::kHoming) homing_ = false;
    a.target = (st->motion == arm::Motion::kMoving || st->motion == arm::Motion::kHolding) ? target_
                                                                                           : a.pose;
    a.speed_m_s = st->speed_m_s;
    a.motion = to_motion(st->motion);
    a.homed = st->homed;
    a.fault_code = st->fault;
    a.fault = arm::fault_text(st->fault);
    const auto& entry = sent_[st->ack_sequence % sent_.size()];
    a.command_sequence = entry.first == st->ack_sequence ? entry.second : st->ack_sequence;
    a.sequence = states_++;
    a.host_ns = now;
    // UPTIME is a 32-bit ms counter: unwrap it into ns.
    if (have_uptime_ && st->uptime_ms < last_uptime_ms_) uptime_wraps_ += 1;
    have_uptime_ = true;
    last_uptime_ms_ = st->uptime_ms;
    a.device_stamp_ns =
        (static_cast<std::int64_t>(uptime_wraps_) << 32 | st->uptime_ms) * 1'000'000;
    return a;
  }

  Status on_stop() override {
    if (!client_) return failed_precondition("arm '" + name() + "': not configured");
    Status s = client_->stop();
    if (!s.ok() && link_down(s)) s = client_->stop();
    return s.ok() ? s : s.with_context("arm '" + name() + "': stop");
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = "Modbus 4-DOF arm (register map 1.0)";
    if (!client_) return;
    const ModbusArmStats st = client_->stats();
    info.details = {{"link", client_->options().describe()},
                    {"connected", client_->connected() ? "yes" : "no"},
                    {"transactions", std::to_string(st.transactions)},
                    {"failures", std::to_string(st.failures)},
                    {"connects", std::to_string(st.connects)}};
  }

 private:
  devices::ArmLimits limits_;
  std::unique_ptr<ModbusArmClient> client_;
  std::uint16_t sequence16_ = 0;
  std::array<std::pair<std::uint16_t, std::uint64_t>, 64> sent_{};  // register seq -> caller seq
  devices::ArmPose target_;
  bool homing_ = false;
  std::uint64_t states_ = 0;
  std::uint64_t reconnects_ = 0;
  bool have_uptime_ = false;
  std::uint32_t last_uptime_ms_ = 0;
  std::uint64_t uptime_wraps_ = 0;
};

}  // namespace

Result<std::unique_ptr<devices::Arm>> make_modbus_arm(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Arm>(new ModbusArm(ctx));
}

}  // namespace hc::rig
