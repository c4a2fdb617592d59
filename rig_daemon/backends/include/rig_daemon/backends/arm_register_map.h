// Modbus register map of the rig's 4-DOF arm (x, y, z, yaw of the tool tip; SCARA-like), spoken by
// the Modbus arm backend (TCP or RTU) and by the arm simulator. Version 1.0 (MAP_VERSION 0x0100).
// The map is ours: the rig's arm controller (a PLC or the simulator) implements it.
//
// Fixed point, SI: lengths are int32 micrometres (1 count = 1e-6 m, range +-2147 m), angles int32
// microradians (1 count = 1e-6 rad), speeds uint32 micrometres per second / microradians per
// second. A 32-bit value takes two consecutive 16-bit registers, HIGH WORD FIRST (libmodbus's
// MODBUS_GET_INT32_FROM_INT16 order; two's complement for signed values). Addresses are 0-based
// protocol addresses (a PLC manual would call holding register 0 "40001").
//
// Holding registers (function 03 read, 16 write multiple, 06 write single):
//
// | addr  | name          | type | unit   | meaning |
// |-------|---------------|------|--------|--------------------------------------------------------|
// | 0     | COMMAND       | u16  |        | 1 home, 2 move to target, 3 set speed, 4 stop, | | | |
// |        | 5 clear fault                                          | | 1     | COMMAND_SEQ   | u16
// |        | the arm executes COMMAND when this changes (mod 2^16)  | | 2-3   | TARGET_X      | i32
// | um     | target pose of the tool tip, base frame                | | 4-5   | TARGET_Y      | i32
// | um     |                                                        | | 6-7   | TARGET_Z      | i32
// | um     |                                                        | | 8-9   | TARGET_YAW    | i32
// | urad   |                                                        | | 10-11 | SPEED         | u32
// | um/s   | Cartesian speed limit (move to: 0 = keep current)      | | 12-13 | YAW_SPEED     | u32
// | urad/s | yaw speed limit (0 = keep current)                     | | 14    | STOP          | u16
// |        | write non-zero (function 06): stop at once; reads 0    | |       |               | |
// | again once the arm stopped                             |
//
// A command is ONE "write multiple registers" transaction (function 16) of addresses 0..13, so
// target, speed and command arrive together; the arm acts on it before answering, so an answered
// write was accepted (or rejected with a fault). STOP is a separate register so a stop is a
// single short write that never races a command.
//
// Input registers (function 04, read-only); the backend reads all 18 in one transaction:
//
// | addr  | name          | type | unit   | meaning |
// |-------|---------------|------|--------|--------------------------------------------------------|
// | 0     | MAP_VERSION   | u16  |        | 0x0100 | | 1     | MOTION        | u16  |        | 0
// idle, 1 homing, 2 moving, 3 holding (at target),     | |       |               |      |        |
// 4 stopped, 5 fault (devices::ArmMotion order)          | | 2     | FAULT         | u16  | | 0
// none, see ArmFault                                   | | 3     | FLAGS         | u16  |        |
// bit 0 homed, bit 1 in motion                           | | 4     | ACK_SEQ       | u16  | |
// COMMAND_SEQ of the last command executed               | | 5-6   | POS_X         | i32  | um |
// measured tool pose                                     | | 7-8   | POS_Y         | i32  | um | |
// | 9-10  | POS_Z         | i32  | um     | | | 11-12 | POS_YAW       | i32  | urad   | | | 13-14 |
// SPEED         | u32  | um/s   | current Cartesian speed limit                          | | 15-16
// | UPTIME        | u32  | ms     | controller clock (the device timestamp; wraps 49.7 d)  | | 17
// | HEARTBEAT     | u16  |        | +1 per control cycle (a frozen controller stops it)    |
//
// Faults (FAULT register): 1 target outside the workspace, 2 speed out of range, 3 unknown
// command, 4 move before homing, 5 following error (the axis could not follow), 6 emergency stop.
// A fault stops the arm; only COMMAND 5 (clear fault) leaves MOTION 5.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "common/status.h"

namespace hc::rig::arm {

inline constexpr std::uint16_t kMapVersion = 0x0100;

// Holding register addresses.
inline constexpr int kRegCommand = 0;
inline constexpr int kRegCommandSeq = 1;
inline constexpr int kRegTargetX = 2;
inline constexpr int kRegTargetY = 4;
inline constexpr int kRegTargetZ = 6;
inline constexpr int kRegTargetYaw = 8;
inline constexpr int kRegSpeed = 10;
inline constexpr int kRegYawSpeed = 12;
inline constexpr int kRegStop = 14;
inline constexpr int kCommandRegisters = 14;  // addresses 0..13, one function-16 write
inline constexpr int kHoldingRegisters = 15;

// Input register addresses.
inline constexpr int kInMapVersion = 0;
inline constexpr int kInMotion = 1;
inline constexpr int kInFault = 2;
inline constexpr int kInFlags = 3;
inline constexpr int kInAckSeq = 4;
inline constexpr int kInPosX = 5;
inline constexpr int kInPosY = 7;
inline constexpr int kInPosZ = 9;
inline constexpr int kInPosYaw = 11;
inline constexpr int kInSpeed = 13;
inline constexpr int kInUptime = 15;
inline constexpr int kInHeartbeat = 17;
inline constexpr int kInputRegisters = 18;

inline constexpr std::uint16_t kFlagHomed = 1u << 0;
inline constexpr std::uint16_t kFlagInMotion = 1u << 1;

// Scale factors (counts per SI unit).
inline constexpr double kCountsPerMetre = 1e6;       // micrometres
inline constexpr double kCountsPerRadian = 1e6;      // microradians
inline constexpr double kCountsPerMetrePerS = 1e6;   // um/s
inline constexpr double kCountsPerRadianPerS = 1e6;  // urad/s

enum class Opcode : std::uint16_t {
  kNone = 0,
  kHome = 1,
  kMoveTo = 2,
  kSetSpeed = 3,
  kStop = 4,
  kClearFault = 5,
};

enum class Motion : std::uint16_t {
  kIdle = 0,
  kHoming = 1,
  kMoving = 2,
  kHolding = 3,
  kStopped = 4,
  kFault = 5,
};

enum class Fault : std::uint16_t {
  kNone = 0,
  kOutsideWorkspace = 1,
  kSpeedOutOfRange = 2,
  kUnknownCommand = 3,
  kNotHomed = 4,
  kFollowingError = 5,
  kEmergencyStop = 6,
};
// Human-readable text; "unknown fault N" for codes outside the table.
std::string fault_text(std::uint16_t code);

// A command as registers 0..13 hold it, in SI.
struct CommandBlock {
  Opcode opcode = Opcode::kNone;
  std::uint16_t sequence = 0;
  double x_m = 0, y_m = 0, z_m = 0, yaw_rad = 0;
  double speed_m_s = 0;        // 0 = keep current
  double yaw_speed_rad_s = 0;  // 0 = keep current
};

// The input registers, in SI.
struct StatusBlock {
  std::uint16_t map_version = kMapVersion;
  Motion motion = Motion::kIdle;
  std::uint16_t fault = 0;
  bool homed = false;
  bool in_motion = false;
  std::uint16_t ack_sequence = 0;
  double x_m = 0, y_m = 0, z_m = 0, yaw_rad = 0;
  double speed_m_s = 0;
  std::uint32_t uptime_ms = 0;
  std::uint16_t heartbeat = 0;
};

// SI value -> fixed-point counts, rounded to nearest. kInvalidArgument (naming `what`) for NaN,
// infinity, or a value outside int32 (uint32 for the unsigned variant) counts.
Result<std::int32_t> to_fixed(double value, double counts_per_unit, const char* what);
Result<std::uint32_t> to_fixed_unsigned(double value, double counts_per_unit, const char* what);

// Two registers, high word first.
void put_i32(std::uint16_t* regs, std::int32_t v);
void put_u32(std::uint16_t* regs, std::uint32_t v);
std::int32_t get_i32(const std::uint16_t* regs);
std::uint32_t get_u32(const std::uint16_t* regs);

// Registers 0..13 for `command`. Fails for a value that does not fit (see to_fixed), a negative
// speed, or opcode kNone.
Result<std::array<std::uint16_t, kCommandRegisters>> encode_command(const CommandBlock& command);
// The arm's side: decodes registers 0..13. kInvalidArgument for fewer than 14 registers; an
// unknown opcode is NOT an error here (the arm answers it with fault 3), it is returned as read.
Result<CommandBlock> decode_command(std::span<const std::uint16_t> registers);

std::array<std::uint16_t, kInputRegisters> encode_status(const StatusBlock& status);
// The client's side: kInvalidArgument for fewer than 18 registers, an unknown MAP_VERSION major
// (high byte != 1), an unknown MOTION value, or FLAGS bits outside 0..1; kFailedPrecondition-free.
Result<StatusBlock> decode_status(std::span<const std::uint16_t> registers);

}  // namespace hc::rig::arm
