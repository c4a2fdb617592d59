#include "rig_daemon/backends/arm_register_map.h"

#include <cmath>
#include <limits>

namespace hc::rig::arm {

std::string fault_text(std::uint16_t code) {
  switch (static_cast<Fault>(code)) {
    case Fault::kNone:
      return "";
    case Fault::kOutsideWorkspace:
      return "target outside the workspace";
    case Fault::kSpeedOutOfRange:
      return "speed out of range";
    case Fault::kUnknownCommand:
      return "unknown command";
    case Fault::kNotHomed:
      return "move before homing";
    case Fault::kFollowingError:
      return "following error";
    case Fault::kEmergencyStop:
      return "emergency stop";
  }
  return "unknown fault " + std::to_string(code);
}

Result<std::int32_t> to_fixed(double value, double counts_per_unit, const char* what) {
  const double c = std::round(value * counts_per_unit);
  if (!std::isfinite(c) || c > std::numeric_limits<std::int32_t>::max() ||
      c < std::numeric_limits<std::int32_t>::min())
    return invalid_argument(std::string(what) + ": " + std::to_string(value) +
                            " does not fit the int32 fixed-point register");
  return static_cast<std::int32_t>(c);
}

Result<std::uint32_t> to_fixed_unsigned(double value, double counts_per_unit, const char* what) {
  const double c = std::round(value * counts_per_unit);
  if (!std::isfinite(c) || c < 0 || c > std::numeric_limits<std::uint32_t>::max())
    return invalid_argument(std::string(what) + ": " + std::to_string(value) +
                            " does not fit the uint32 fixed-point register");
  return static_cast<std::uint32_t>(c);
}

void put_u32(std::uint16_t* regs, std::uint32_t v) {
  regs[0] = static_cast<std::uint16_t>(v >> 16);
  regs[1] = static_cast<std::uint16_t>(v & 0xFFFFu);
}
void put_i32(std::uint16_t* regs, std::int32_t v) { put_u32(regs, static_cast<std::uint32_t>(v)); }
std::uint32_t get_u32(const std::uint16_t* regs) {
  return (static_cast<std::uint32_t>(regs[0]) << 16) | regs[1];
}
std::int32_t get_i32(const std::uint16_t* regs) { return static_cast<std::int32_t>(get_u32(regs)); }

Result<std::array<std::uint16_t, kCommandRegisters>> encode_command(const CommandBlock& c) {
  if (c.opcode == Opcode::kNone) return invalid_argument("arm command: no opcode");
  std::array<std::uint16_t, kCommandRegisters> r{};
  r[kRegCommand] = static_cast<std::uint16_t>(c.opcode);
  r[kRegCommandSeq] = c.sequence;
  HC_ASSIGN_OR_RETURN(std::int32_t x, to_fixed(c.x_m, kCountsPerMetre, "target x"));
  HC_ASSIGN_OR_RETURN(std::int32_t y, to_fixed(c.y_m, kCountsPerMetre, "target y"));
  HC_ASSIGN_OR_RETURN(std::int32_t z, to_fixed(c.z_m, kCountsPerMetre, "target z"));
  HC_ASSIGN_OR_RETURN(std::int32_t yaw, to_fixed(c.yaw_rad, kCountsPerRadian, "target yaw"));
  HC_ASSIGN_OR_RETURN(std::uint32_t speed,
                      to_fixed_unsigned(c.speed_m_s, kCountsPerMetrePerS, "speed"));
  HC_ASSIGN_OR_RETURN(std::uint32_t yaw_speed,
                      to_fixed_unsigned(c.yaw_speed_rad_s, kCountsPerRadianPerS, "yaw speed"));
  put_i32(&r[kRegTargetX], x);
  put_i32(&r[kRegTargetY], y);
  put_i32(&r[kRegTargetZ], z);
  put_i32(&r[kRegTargetYaw], yaw);
  put_u32(&r[kRegSpeed], speed);
  put_u32(&r[kRegYawSpeed], yaw_speed);
  return r;
}

Result<CommandBlock> decode_command(std::span<const std::uint16_t> r) {
  if (r.size() < static_cast<std::size_t>(kCommandRegisters))
    return invalid_argument("arm command: expected 14 registers, got " + std::to_string(r.size()));
  CommandBlock c;
  c.opcode = static_cast<Opcode>(r[kRegCommand]);
  c.sequence = r[kRegCommandSeq];
  c.x_m = get_i32(&r[kRegTargetX]) / kCountsPerMetre;
  c.y_m = get_i32(&r[kRegTargetY]) / kCountsPerMetre;
  c.z_m = get_i32(&r[kRegTargetZ]) / kCountsPerMetre;
  c.yaw_rad = get_i32(&r[kRegTargetYaw]) / kCountsPerRadian;
  c.speed_m_s = get_u32(&r[kRegSpeed]) / kCountsPerMetrePerS;
  c.yaw_speed_rad_s = get_u32(&r[kRegYawSpeed]) / kCountsPerRadianPerS;
  return c;
}

std::array<std::uint16_t, kInputRegisters> encode_status(const StatusBlock& s) {
  std::array<std::uint16_t, kInputRegisters> r{};
  r[kInMapVersion] = s.map_version;
  r[kInMotion] = static_cast<std::uint16_t>(s.motion);
  r[kInFault] = s.fault;
  r[kInFlags] =
      static_cast<std::uint16_t>((s.homed ? kFlagHomed : 0) | (s.in_motion ? kFlagInMotion : 0));
  r[kInAckSeq] = s.ack_sequence;
  // The arm's own values are always in range; saturate rather than fail.
  auto fixed = [](double v, double k) {
    auto f = to_fixed(v, k, "");
    return f.ok() ? *f
                  : (v > 0 ? std::numeric_limits<std::int32_t>::max()
                           : std::numeric_limits<std::int32_t>::min());
  };
  put_i32(&r[kInPosX], fixed(s.x_m, kCountsPerMetre));
  put_i32(&r[kInPosY], fixed(s.y_m, kCountsPerMetre));
  put_i32(&r[kInPosZ], fixed(s.z_m, kCountsPerMetre));
  put_i32(&r[kInPosYaw], fixed(s.yaw_rad, kCountsPerRadian));
  auto speed = to_fixed_unsigned(s.speed_m_s, kCountsPerMetrePerS, "");
  put_u32(&r[kInSpeed], speed.ok() ? *speed : 0);
  put_u32(&r[kInUptime], s.uptime_ms);
  r[kInHeartbeat] = s.heartbeat;
  return r;
}

Result<StatusBlock> decode_status(std::span<const std::uint16_t> r) {
  if (r.size() < static_cast<std::size_t>(kInputRegisters))
    return invalid_argument("arm status: expected 18 input registers, got " +
                            std::to_string(r.size()));
  StatusBlock s;
  s.map_version = r[kInMapVersion];
  if ((s.map_version >> 8) != (kMapVersion >> 8))
    return invalid_argument("arm status: register map version " +
                            std::to_string(s.map_version >> 8) + "." +
                            std::to_string(s.map_version & 0xFF) + ", expected 1.x");
  if (r[kInMotion] > static_cast<std::uint16_t>(Motion::kFault))
    return invalid_argument("arm status: MOTION " + std::to_string(r[kInMotion]) +
                            " is not one of 0..5");
  s.motion = static_cast<Motion>(r[kInMotion]);
  s.fault = r[kInFault];
  if ((r[kInFlags] & ~(kFlagHomed | kFlagInMotion)) != 0)
    return invalid_argument("arm status: FLAGS " + std::to_string(r[kInFlags]) +
                            " has bits other than 0 (homed) and 1 (in motion)");
  s.homed = (r[kInFlags] & kFlagHomed) != 0;
  s.in_motion = (r[kInFlags] & kFlagInMotion) != 0;
  s.ack_sequence = r[kInAckSeq];
  s.x_m = get_i32(&r[kInPosX]) / kCountsPerMetre;
  s.y_m = get_i32(&r[kInPosY]) / kCountsPerMetre;
  s.z_m = get_i32(&r[kInPosZ]) / kCountsPerMetre;
  s.yaw_rad = get_i32(&r[kInPosYaw]) / kCountsPerRadian;
  s.speed_m_s = get_u32(&r[kInSpeed]) / kCountsPerMetrePerS;
  s.uptime_ms = get_u32(&r[kInUptime]);
  s.heartbeat = r[kInHeartbeat];
  return s;
}

}  // namespace hc::rig::arm
