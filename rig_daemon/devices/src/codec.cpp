#include "rig_daemon/devices/codec.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

namespace hc::devices {

namespace {

using Json = nlohmann::json;

// Invalid UTF-8 in a string (a device's fault text) is replaced rather than thrown on.
std::string dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

// Strict field readers: each records the first problem and leaves the value untouched.
class Reader {
 public:
  Reader(const Json& j, std::string_view type) : j_(j), type_(type) {}

  template <typename T>
  void req(const char* key, T& out) {
    if (!status_.ok()) return;
    auto it = j_.find(key);
    if (it == j_.end()) {
      status_ = invalid_argument(std::string(type_) + ": missing field '" + key + "'");
      return;
    }
    get(*it, key, out);
  }
  template <typename T>
  void opt(const char* key, std::optional<T>& out) {
    if (!status_.ok()) return;
    auto it = j_.find(key);
    if (it == j_.end() || it->is_null()) return;
    T v{};
    if (get(*it, key, v)) out = v;
  }
  template <typename T, std::size_t N>
  void req(const char* key, std::array<T, N>& out) {
    if (!status_.ok()) return;
    auto it = j_.find(key);
    if (it == j_.end() || !it->is_array() || it->size() != N) {
      status_ = invalid_argument(std::string(type_) + ": field '" + key + "' must be an array of " +
                                 std::to_string(N) + " numbers");
      return;
    }
    for (std::size_t i = 0; i < N; ++i) get((*it)[i], key, out[i]);
  }
  const Json* object(const char* key) {
    if (!status_.ok()) return nullptr;
    auto it = j_.find(key);
    if (it == j_.end() || !it->is_object()) {
      status_ = invalid_argument(std::string(type_) + ": field '" + key + "' must be an object");
      return nullptr;
    }
    return &*it;
  }
  void fail(std::string message) {
    if (status_.ok()) status_ = invalid_argument(std::string(type_) + ": " + message);
  }
  const Status& status() const { return status_; }

 private:
  template <typename T>
  bool get(const Json& v, const char* key, T& out) {
    if constexpr (std::is_same_v<T, bool>) {
      if (v.is_boolean()) {
        out = v.get<bool>();
        return true;
      }
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (v.is_string()) {
        out = v.get<std::string>();
        return true;
      }
    } else if constexpr (std::is_floating_point_v<T>) {
      if (v.is_number()) {
        out = v.get<double>();
        return true;
      }
    } else if constexpr (std::is_integral_v<T>) {
      if (v.is_number_unsigned()) {
        const auto u = v.get<std::uint64_t>();
        if (u <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())) {
          out = static_cast<T>(u);
          return true;
        }
      } else if (v.is_number_integer()) {
        const auto s = v.get<std::int64_t>();
        if (std::is_signed_v<T> && s >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
            s <= static_cast<std::int64_t>(std::numeric_limits<T>::max())) {
          out = static_cast<T>(s);
          return true;
        }
      }
    }
    status_ = invalid_argument(std::string(type_) + ": field '" + key +
                               "' has the wrong type or is out of range");
    return false;
  }

  const Json& j_;
  std::string_view type_;
  Status status_;
};

Result<Json> parse_object(std::string_view text, std::string_view type) {
  Json j = Json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return invalid_argument(std::string(type) + ": not a JSON object");
  return j;
}

template <typename T>
void put_opt(Json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}

// JSON has no NaN/inf: non-finite doubles are written as null and read back as NaN.
Json num(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

Json pose_json(const ArmPose& p) {
  return Json{
      {"x_m", num(p.x_m)}, {"y_m", num(p.y_m)}, {"z_m", num(p.z_m)}, {"yaw_rad", num(p.yaw_rad)}};
}
void read_pose(Reader& r, const char* key, ArmPose& p) {
  const Json* o = r.object(key);
  if (!o) return;
  Reader pr(*o, key);
  pr.req("x_m", p.x_m);
  pr.req("y_m", p.y_m);
  pr.req("z_m", p.z_m);
  pr.req("yaw_rad", p.yaw_rad);
  if (!pr.status().ok()) r.fail(pr.status().message());
}

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
         {"force_n", num(s.force_n)},
         {"channel", s.channel},
         {"sequence", s.sequence},
         {"host_ns", s.host_ns}};
  put_opt(j, "device_stamp_ns", s.device_stamp_ns);
  put_opt(j, "trigger_index", s.trigger_index);
  return dump(j);
}

std::string to_json(const WrenchSample& s) {
  Json j{{"counts", s.counts},
         {"force_n", {num(s.force_n[0]), num(s.force_n[1]), num(s.force_n[2])}},
         {"torque_nm", {num(s.torque_nm[0]), num(s.torque_nm[1]), num(s.torque_nm[2])}},
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
         {"joints", {num(s.joints[0]), num(s.joints[1]), num(s.joints[2]), num(s.joints[3])}},
         {"speed_m_s", num(s.speed_m_s)},
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
         {"speed_m_s", num(c.speed_m_s)},
         {"sequence", c.sequence}};
  return dump(j);
}

Result<TriggerEdge> trigger_edge_from_json(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Json j, parse_object(text, "hardcopy.TriggerEdge"));
  Reader r(j, "hardcopy.TriggerEdge");
  TriggerEdge e;
  r.req("index", e.index);
  r.req("line", e.line);
  r.req("rising", e.rising);
  r.req("host_ns", e.host_ns);
  r.req("device_counter", e.device_counter);
  r.opt("device_stamp_ns", e.device_stamp_ns);
  if (!r.status().ok()) return r.status();
  return e;
}

Result<FsrSample> fsr_sample_from_json(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Json j, parse_object(text, "hardcopy.FsrSample"));
  Reader r(j, "hardcopy.FsrSample");
  FsrSample s;
  r.req("raw", s.raw);
  if (j.contains("force_n") && j["force_n"].is_null())
    s.force_n = std::numeric_limits<double>::quiet_NaN();
  else
    r.req("force_n", s.force_n);
  r.req("channel", s.channel);
  r.req("sequence", s.sequence);
  r.req("host_ns", s.host_ns);
  r.opt("device_stamp_ns", s.device_stamp_ns);
  r.opt("trigger_index", s.trigger_index);
  if (!r.status().ok()) return r.status();
  return s;
}

Result<WrenchSample> wrench_sample_from_json(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Json j, parse_object(text, "hardcopy.WrenchSample"));
  Reader r(j, "hardcopy.WrenchSample");
  WrenchSample s;
  r.req("counts", s.counts);
  for (const char* key : {"force_n", "torque_nm"}) {
    auto it = j.find(key);
    if (it == j.end() || !it->is_array() || it->size() != 3) {
      r.fail(std::string("field '") + key + "' must be an array of 3 numbers");
      continue;
    }
    auto& dst = std::string_view(key) == "force_n" ? s.force_n : s.torque_nm;
    for (std::size_t i = 0; i < 3; ++i) {
      const Json& v = (*it)[i];
      if (v.is_number())
        dst[i] = v.get<double>();
      else if (v.is_null())
        dst[i] = std::numeric_limits<double>::quiet_NaN();
      else
        r.fail(std::string("field '") + key + "' must hold numbers");
    }
  }
  r.req("rdt_sequence", s.rdt_sequence);
  r.req("ft_sequence", s.ft_sequence);
  r.req("status", s.status);
  r.req("sequence", s.sequence);
  r.req("host_ns", s.host_ns);
  r.opt("device_stamp_ns", s.device_stamp_ns);
  r.opt("trigger_index", s.trigger_index);
  if (!r.status().ok()) return r.status();
  return s;
}

Result<ArmState> arm_state_from_json(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Json j, parse_object(text, "hardcopy.ArmState"));
  Reader r(j, "hardcopy.ArmState");
  ArmState s;
  read_pose(r, "pose", s.pose);
  read_pose(r, "target", s.target);
  r.req("joints", s.joints);
  r.req("speed_m_s", s.speed_m_s);
  std::string motion;
  r.req("motion", motion);
  if (r.status().ok()) {
    bool found = false;
    for (ArmMotion m : {ArmMotion::kIdle, ArmMotion::kHoming, ArmMotion::kMoving,
                        ArmMotion::kHolding, ArmMotion::kStopped, ArmMotion::kFault})
      if (to_string(m) == motion) {
        s.motion = m;
        found = true;
      }
    if (!found) r.fail("unknown motion '" + motion + "'");
  }
  r.req("homed", s.homed);
  r.req("fault_code", s.fault_code);
  r.req("fault", s.fault);
  r.req("command_sequence", s.command_sequence);
  r.req("sequence", s.sequence);
  r.req("host_ns", s.host_ns);
  r.opt("device_stamp_ns", s.device_stamp_ns);
  if (!r.status().ok()) return r.status();
  return s;
}

Result<ArmCommand> arm_command_from_json(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Json j, parse_object(text, "hardcopy.ArmCommand"));
  Reader r(j, "hardcopy.ArmCommand");
  ArmCommand c;
  std::string type;
  r.req("type", type);
  if (r.status().ok()) {
    bool found = false;
    for (ArmCommand::Type t :
         {ArmCommand::Type::kHome, ArmCommand::Type::kMoveTo, ArmCommand::Type::kSetSpeed,
          ArmCommand::Type::kStop, ArmCommand::Type::kClearFault})
      if (to_string(t) == type) {
        c.type = t;
        found = true;
      }
    if (!found) r.fail("unknown command type '" + type + "'");
  }
  read_pose(r, "target", c.target);
  r.req("speed_m_s", c.speed_m_s);
  r.req("sequence", c.sequence);
  if (!r.status().ok()) return r.status();
  return c;
}

}  // namespace hc::devices
