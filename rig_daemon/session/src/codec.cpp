#include "rig_daemon/session/codec.h"

#include <array>
#include <string>

#include "common/json.h"
#include "common/json_reader.h"
#include "codec_internal.h"

namespace hc::session {

namespace {

using namespace detail;

constexpr std::string_view kTriggerEdgeSchema = R"({
  "title": "hardcopy.TriggerEdge",
  "type": "object",
  "properties": {
    "index": {"type": "integer", "minimum": 0},
    "line": {"type": "integer", "minimum": 0},
    "rising": {"type": "boolean"},
    "host_ns": {"type": "integer", "description": "host monotonic time, ns"},
    "device_stamp_ns": {"type": "integer", "description": "device clock, ns"},
    "device_counter": {"type": "integer", "minimum": 0}
  },
  "required": ["index", "line", "rising", "host_ns", "device_counter"]
})";

constexpr std::string_view kFsrSampleSchema = R"({
  "title": "hardcopy.FsrSample",
  "type": "object",
  "properties": {
    "raw": {"type": "integer", "minimum": 0, "description": "ADC counts"},
    "force_n": {"type": "number", "description": "N, through the recorded calibration"},
    "channel": {"type": "integer", "minimum": 0},
    "sequence": {"type": "integer", "minimum": 0},
    "host_ns": {"type": "integer"},
    "device_stamp_ns": {"type": "integer"},
    "trigger_index": {"type": "integer", "minimum": 0}
  },
  "required": ["raw", "force_n", "channel", "sequence", "host_ns"]
})";

constexpr std::string_view kWrenchSampleSchema = R"({
  "title": "hardcopy.WrenchSample",
  "type": "object",
  "properties": {
    "counts": {"type": "array", "items": {"type": "integer"}, "minItems": 6, "maxItems": 6,
               "description": "Fx Fy Fz Tx Ty Tz raw counts"},
    "force_n": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
    "torque_nm": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
    "rdt_sequence": {"type": "integer", "minimum": 0},
    "ft_sequence": {"type": "integer", "minimum": 0},
    "status": {"type": "integer", "minimum": 0},
    "sequence": {"type": "integer", "minimum": 0},
    "host_ns": {"type": "integer"},
    "device_stamp_ns": {"type": "integer"},
    "trigger_index": {"type": "integer", "minimum": 0}
  },
  "required": ["counts", "force_n", "torque_nm", "rdt_sequence", "ft_sequence", "status",
               "sequence", "host_ns"]
})";

constexpr std::string_view kPoseSchema =
    R"({"type": "object", "properties": {"x_m": {"type": "number"}, "y_m": {"type": "number"}, "z_m": {"type": "number"}, "yaw_rad": {"type": "number"}}, "required": ["x_m", "y_m", "z_m", "yaw_rad"]})";

const std::string& arm_state_schema_text() {
  static const std::string s = std::string(R"({
  "title": "hardcopy.ArmState",
  "type": "object",
  "properties": {
    "pose": )") + std::string(kPoseSchema) +
                               R"(,
    "target": )" + std::string(kPoseSchema) +
                               R"(,
    "joints": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4},
    "speed_m_s": {"type": "number"},
    "motion": {"enum": ["idle", "homing", "moving", "holding", "stopped", "fault"]},
    "homed": {"type": "boolean"},
    "fault_code": {"type": "integer", "minimum": 0},
    "fault": {"type": "string"},
    "command_sequence": {"type": "integer", "minimum": 0},
    "sequence": {"type": "integer", "minimum": 0},
    "host_ns": {"type": "integer"},
    "device_stamp_ns": {"type": "integer"}
  },
  "required": ["pose", "target", "joints", "speed_m_s", "motion", "homed", "fault_code", "fault",
               "command_sequence", "sequence", "host_ns"]
})";
  return s;
}

const std::string& arm_command_schema_text() {
  static const std::string s = std::string(R"({
  "title": "hardcopy.ArmCommand",
  "type": "object",
  "properties": {
    "type": {"enum": ["home", "move_to", "set_speed", "stop", "clear_fault"]},
    "target": )") + std::string(kPoseSchema) +
                               R"(,
    "speed_m_s": {"type": "number"},
    "sequence": {"type": "integer", "minimum": 0}
  },
  "required": ["type", "target", "speed_m_s", "sequence"]
})";
  return s;
}

}  // namespace

const MessageSchema& trigger_edge_schema() {
  static const MessageSchema s{"hardcopy.TriggerEdge", kTriggerEdgeSchema};
  return s;
}
const MessageSchema& fsr_sample_schema() {
  static const MessageSchema s{"hardcopy.FsrSample", kFsrSampleSchema};
  return s;
}
const MessageSchema& wrench_sample_schema() {
  static const MessageSchema s{"hardcopy.WrenchSample", kWrenchSampleSchema};
  return s;
}
const MessageSchema& arm_state_schema() {
  static const MessageSchema s{"hardcopy.ArmState", arm_state_schema_text()};
  return s;
}
const MessageSchema& arm_command_schema() {
  static const MessageSchema s{"hardcopy.ArmCommand", arm_command_schema_text()};
  return s;
}

std::string to_json(const TriggerEdge& e) {
  Json j{{"index", e.index},
         {"line", e.line},
         {"rising", e.rising},
         {"host_ns", e.host_ns},
         {"device_counter", e.device_counter}};
  put_opt(j, "device_stamp_ns", e.device_stamp_ns);
  return dump(j);
}

std::string to_json(const FsrSample& s) {
  Json j{{"raw", s.raw},
         {"force_n", finite_or_null(s.force_n)},
         {"channel", s.channel},
         {"sequence", s.sequence},
         {"host_ns", s.host_ns}};
  put_opt(j, "device_stamp_ns", s.device_stamp_ns);
  put_opt(j, "trigger_index", s.trigger_index);
  return dump(j);
}

std::string to_json(const WrenchSample& s) {
  Json j{
      {"counts", s.counts},
      {"force_n",
       {finite_or_null(s.force_n[0]), finite_or_null(s.force_n[1]), finite_or_null(s.force_n[2])}},
      {"torque_nm",
       {finite_or_null(s.torque_nm[0]), finite_or_null(s.torque_nm[1]),
        finite_or_null(s.torque_nm[2])}},
      {"rdt_sequence", s.rdt_sequence},
      {"ft_sequence", s.ft_sequence},
      {"status", s.status},
      {"sequence", s.sequence},
      {"host_ns", s.host_ns}};
  put_opt(j, "device_stamp_ns", s.device_stamp_ns);
  put_opt(j, "trigger_index", s.trigger_index);
  return dump(j);
}

std::string to_json(const ArmState& s) {
  Json j{{"pose", pose_json(s.pose)},
         {"target", pose_json(s.target)},
         {"joints",
          {finite_or_null(s.joints[0]), finite_or_null(s.joints[1]), finite_or_null(s.joints[2]),
           finite_or_null(s.joints[3])}},
         {"speed_m_s", finite_or_null(s.speed_m_s)},
         {"motion", std::string(to_string(s.motion))},
         {"homed", s.homed},
         {"fault_code", s.fault_code},
         {"fault", s.fault},
         {"command_sequence", s.command_sequence},
         {"sequence", s.sequence},
         {"host_ns", s.host_ns}};
  put_opt(j, "device_stamp_ns", s.device_stamp_ns);
  return dump(j);
}

std::string to_json(const ArmCommand& c) {
  Json j{{"type", std::string(to_string(c.type))},
         {"target", pose_json(c.target)},
         {"speed_m_s", finite_or_null(c.speed_m_s)},
         {"sequence", c.sequence}};
  return dump(j);
}

Result<TriggerEdge> trigger_edge_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.TriggerEdge";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  TriggerEdge e;
  HC_RETURN_IF_ERROR(r.get("index", e.index));
  HC_RETURN_IF_ERROR(r.get("line", e.line));
  HC_RETURN_IF_ERROR(r.get("rising", e.rising));
  HC_RETURN_IF_ERROR(r.get("host_ns", e.host_ns));
  HC_RETURN_IF_ERROR(r.get("device_counter", e.device_counter));
  HC_RETURN_IF_ERROR(r.optional("device_stamp_ns", e.device_stamp_ns));
  return e;
}

Result<FsrSample> fsr_sample_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.FsrSample";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  FsrSample s;
  HC_RETURN_IF_ERROR(r.get("raw", s.raw));
  HC_ASSIGN_OR_RETURN(const JsonNode force, r.member("force_n"));
  HC_ASSIGN_OR_RETURN(s.force_n, force.number_or_null());
  HC_RETURN_IF_ERROR(r.get("channel", s.channel));
  HC_RETURN_IF_ERROR(r.get("sequence", s.sequence));
  HC_RETURN_IF_ERROR(r.get("host_ns", s.host_ns));
  HC_RETURN_IF_ERROR(r.optional("device_stamp_ns", s.device_stamp_ns));
  HC_RETURN_IF_ERROR(r.optional("trigger_index", s.trigger_index));
  return s;
}

Result<WrenchSample> wrench_sample_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.WrenchSample";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  WrenchSample s;
  HC_RETURN_IF_ERROR(r.get("counts", s.counts));
  HC_RETURN_IF_ERROR(read_measurements(r, "force_n", s.force_n));
  HC_RETURN_IF_ERROR(read_measurements(r, "torque_nm", s.torque_nm));
  HC_RETURN_IF_ERROR(r.get("rdt_sequence", s.rdt_sequence));
  HC_RETURN_IF_ERROR(r.get("ft_sequence", s.ft_sequence));
  HC_RETURN_IF_ERROR(r.get("status", s.status));
  HC_RETURN_IF_ERROR(r.get("sequence", s.sequence));
  HC_RETURN_IF_ERROR(r.get("host_ns", s.host_ns));
  HC_RETURN_IF_ERROR(r.optional("device_stamp_ns", s.device_stamp_ns));
  HC_RETURN_IF_ERROR(r.optional("trigger_index", s.trigger_index));
  return s;
}

Result<ArmState> arm_state_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.ArmState";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  ArmState s;
  HC_RETURN_IF_ERROR(read_pose(r, "pose", s.pose));
  HC_RETURN_IF_ERROR(read_pose(r, "target", s.target));
  HC_RETURN_IF_ERROR(r.get("joints", s.joints));
  HC_RETURN_IF_ERROR(r.get("speed_m_s", s.speed_m_s));
  std::string motion;
  HC_RETURN_IF_ERROR(
      r.get("motion", motion, {"idle", "homing", "moving", "holding", "stopped", "fault"}));
  for (ArmMotion m : {ArmMotion::kIdle, ArmMotion::kHoming, ArmMotion::kMoving, ArmMotion::kHolding,
                      ArmMotion::kStopped, ArmMotion::kFault})
    if (to_string(m) == motion) s.motion = m;
  HC_RETURN_IF_ERROR(r.get("homed", s.homed));
  HC_RETURN_IF_ERROR(r.get("fault_code", s.fault_code));
  HC_RETURN_IF_ERROR(r.get("fault", s.fault));
  HC_RETURN_IF_ERROR(r.get("command_sequence", s.command_sequence));
  HC_RETURN_IF_ERROR(r.get("sequence", s.sequence));
  HC_RETURN_IF_ERROR(r.get("host_ns", s.host_ns));
  HC_RETURN_IF_ERROR(r.optional("device_stamp_ns", s.device_stamp_ns));
  return s;
}

Result<ArmCommand> arm_command_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.ArmCommand";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  ArmCommand c;
  std::string type;
  HC_RETURN_IF_ERROR(r.get("type", type, {"home", "move_to", "set_speed", "stop", "clear_fault"}));
  for (ArmCommand::Type t :
       {ArmCommand::Type::kHome, ArmCommand::Type::kMoveTo, ArmCommand::Type::kSetSpeed,
        ArmCommand::Type::kStop, ArmCommand::Type::kClearFault})
    if (to_string(t) == type) c.type = t;
  HC_RETURN_IF_ERROR(read_pose(r, "target", c.target));
  HC_RETURN_IF_ERROR(r.get("speed_m_s", c.speed_m_s));
  HC_RETURN_IF_ERROR(r.get("sequence", c.sequence));
  return c;
}

}  // namespace hc::session
