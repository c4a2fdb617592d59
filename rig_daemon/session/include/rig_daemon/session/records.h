// The records a rig session holds (topics.h says on which channel): the samples devices produce
// -- trigger edges, FSR and force-torque samples, arm commands and states. The daemon writes them
// through the codecs (codec.h), the replay backends and the offline rooms read them back; devices
// name them in their own namespace too (rig_daemon/devices/types.h).
//
// Every sample carries
//  * host_ns: host monotonic time (ns, on the Clock the device was created with) at which the host
//    received the sample, and
//  * the device's own counter (sequence number) and, when the device has a clock, device_stamp_ns
//    (ns on the device's time line, which is NOT the host's; e.g. the firmware's µs timer × 1000).
// trigger_index, when set, is the index of the trigger edge (TriggerEdge::index) that caused the
// sample; backends set it only when the device itself tells them (firmware ADC sample latched on an
// edge); otherwise the scheduler associates by time.
//
// SI units throughout (m, rad, N, N·m, s); names carry units.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace hc::session {

// ---------------------------------------------------------------------------------------------
// Trigger

// One edge of a trigger output (or input) line.
struct TriggerEdge {
  // Pulses since activate(), counting from 0; a rising and the following falling edge of one
  // pulse share the index. Frames and samples refer to the rising edge's index.
  std::uint64_t index = 0;
  std::uint32_t line = 0;  // output line (GPIO offset, firmware channel)
  bool rising = true;
  std::int64_t host_ns = 0;                     // host monotonic ns of the edge
  std::optional<std::int64_t> device_stamp_ns;  // e.g. firmware µs timer × 1000
  std::uint64_t device_counter = 0;             // the device's own edge/pulse counter
};

// ---------------------------------------------------------------------------------------------
// Force-sensing resistor (FSR)

struct FsrSample {
  std::uint32_t raw = 0;       // ADC counts (or the Phidget's 0..1000 value)
  double force_n = 0.0;        // raw through the device's FsrCalibration
  std::uint32_t channel = 0;   // ADC channel / InterfaceKit sensor index
  std::uint64_t sequence = 0;  // device counter (samples since activate, unwrapped)
  std::int64_t host_ns = 0;
  std::optional<std::int64_t> device_stamp_ns;
  std::optional<std::uint64_t> trigger_index;
};

// ---------------------------------------------------------------------------------------------
// Six-axis force-torque sensor

struct WrenchSample {
  std::array<std::int32_t, 6> counts{};  // Fx Fy Fz Tx Ty Tz raw counts, before bias
  std::array<double, 3> force_n{};       // bias removed, sensor frame
  std::array<double, 3> torque_nm{};     // bias removed, sensor frame
  std::uint32_t rdt_sequence = 0;        // RDT record sequence (per UDP record)
  std::uint32_t ft_sequence = 0;         // sensor's internal sample counter
  std::uint32_t status = 0;              // sensor status word (0 = healthy)
  std::uint64_t sequence = 0;            // samples since activate, unwrapped, gaps = lost
  std::int64_t host_ns = 0;
  std::optional<std::int64_t> device_stamp_ns;
  std::optional<std::uint64_t> trigger_index;
};

// ---------------------------------------------------------------------------------------------
// 4-DOF arm (x, y, z and yaw of the tool; a SCARA-like arm pressing a vertical probe)

// Pose of the tool tip in the arm's base frame.
struct ArmPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double yaw_rad = 0.0;
};

enum class ArmMotion : std::uint8_t {
  kIdle,  // powered, not homed or holding position
  kHoming,
  kMoving,
  kHolding,  // reached the target
  kStopped,  // stopped by stop(); needs a new command
  kFault,    // see ArmState::fault_code; needs clear_fault
};
std::string_view to_string(ArmMotion motion);

struct ArmCommand {
  enum class Type : std::uint8_t { kHome, kMoveTo, kSetSpeed, kStop, kClearFault };
  Type type = Type::kMoveTo;
  ArmPose target;              // kMoveTo
  double speed_m_s = 0.0;      // kSetSpeed, or kMoveTo when > 0 (else the current speed)
  std::uint64_t sequence = 0;  // caller's command counter (echoed in ArmState::command_sequence)
};
std::string_view to_string(ArmCommand::Type type);

struct ArmState {
  ArmPose pose;                    // measured tool pose
  ArmPose target;                  // current target
  std::array<double, 4> joints{};  // joint values (m or rad per joint), when the arm reports them
  double speed_m_s = 0.0;          // configured Cartesian speed limit
  ArmMotion motion = ArmMotion::kIdle;
  bool homed = false;
  std::uint32_t fault_code = 0;        // 0 = none
  std::string fault;                   // human-readable fault, empty when none
  std::uint64_t command_sequence = 0;  // sequence of the last accepted command
  std::uint64_t sequence = 0;          // states read since activate
  std::int64_t host_ns = 0;
  std::optional<std::int64_t> device_stamp_ns;
};

}  // namespace hc::session
