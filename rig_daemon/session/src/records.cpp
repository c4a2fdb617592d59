#include "rig_daemon/session/records.h"

namespace hc::session {

std::string_view to_string(ArmMotion motion) {
  switch (motion) {
    case ArmMotion::kIdle:
      return "idle";
    case ArmMotion::kHoming:
      return "homing";
    case ArmMotion::kMoving:
      return "moving";
    case ArmMotion::kHolding:
      return "holding";
    case ArmMotion::kStopped:
      return "stopped";
    case ArmMotion::kFault:
      return "fault";
  }
  return "unknown";
}

std::string_view to_string(ArmCommand::Type type) {
  switch (type) {
    case ArmCommand::Type::kHome:
      return "home";
    case ArmCommand::Type::kMoveTo:
      return "move_to";
    case ArmCommand::Type::kSetSpeed:
      return "set_speed";
    case ArmCommand::Type::kStop:
      return "stop";
    case ArmCommand::Type::kClearFault:
      return "clear_fault";
  }
  return "unknown";
}

}  // namespace hc::session
