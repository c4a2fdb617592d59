// Codecs of the session's own records (session_records.h): sync, step, event and ground truth.
#include <fmt/format.h>

#include <string>

#include "codec_internal.h"
#include "rig_daemon/session/codec.h"

namespace hc::session {

namespace {

using namespace detail;

constexpr std::string_view kSyncSchema = R"({
  "title": "hardcopy.SyncRecord",
  "type": "object",
  "properties": {
    "trigger_index": {"type": "integer", "minimum": 0},
    "edge_host_ns": {"type": "integer", "description": "host monotonic ns of the rising edge"},
    "complete": {"type": "boolean"},
    "frames": {"type": "object", "additionalProperties": {"type": "integer", "minimum": 0},
               "description": "camera -> frame_index"},
    "missing_cameras": {"type": "array", "items": {"type": "string"}},
    "ft_sequence": {"type": "integer", "minimum": 0},
    "ft_error_ns": {"type": "integer", "description": "F/T sample host time - edge host time, ns"},
    "force_n": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3,
                "description": "Fx Fy Fz, N"},
    "fsr_sequence": {"type": "integer", "minimum": 0},
    "fsr_error_ns": {"type": "integer"},
    "fsr_raw": {"type": "integer", "minimum": 0},
    "fsr_force_n": {"type": "number", "description": "N"}
  },
  "required": ["trigger_index", "edge_host_ns", "complete", "frames", "missing_cameras"]
})";

constexpr std::string_view kStepSchema = R"({
  "title": "hardcopy.Step",
  "type": "object",
  "properties": {
    "host_ns": {"type": "integer"},
    "step": {"type": "integer"},
    "trigger_indices": {"type": "array", "items": {"type": "integer", "minimum": 0}},
    "location": {"type": "integer", "minimum": 0},
    "level": {"type": "integer", "minimum": 0},
    "target_force_n": {"type": "number"},
    "force_n": {"type": "number"},
    "depth_m": {"type": "number"},
    "pose": {"type": "object", "description": "x_m, y_m, z_m, yaw_rad of the tool tip"},
    "board_pose": {"type": "integer", "minimum": 0,
                   "description": "calibration: index of the board pose"}
  },
  "required": ["host_ns", "step", "trigger_indices"]
})";

constexpr std::string_view kEventSchema = R"({
  "title": "hardcopy.Event",
  "type": "object",
  "properties": {
    "host_ns": {"type": "integer"},
    "kind": {"type": "string"},
    "message": {"type": "string"},
    "detected_ns": {"type": "integer"},
    "stop_sent_ns": {"type": "integer"},
    "sample_host_ns": {"type": "integer"},
    "force_n": {"type": "number"},
    "latency_ns": {"type": "integer"}
  },
  "required": ["host_ns", "kind", "message"]
})";

constexpr std::string_view kGroundTruthSchema = R"({
  "title": "hardcopy.GroundTruth",
  "type": "object",
  "properties": {
    "host_ns": {"type": "integer"},
    "trigger_index": {"type": "integer", "minimum": 0},
    "probe": {"type": "object", "description": "x_m, y_m, z_m, yaw_rad of the tool tip"},
    "indentation_m": {"type": "number"},
    "force_n": {"type": "number", "description": "true contact force, N"},
    "markers_m": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
    "probe_tip_m": {"type": "array", "items": {"type": "number"}},
    "probe_axis": {"type": "array", "items": {"type": "number"}},
    "probe_radius_m": {"type": "number"},
    "probe_shown": {"type": "boolean"},
    "shaft_markers_m": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
    "shaft_marker_radius_m": {"type": "number"},
    "cameras": {"type": "object",
                "description": "camera -> {occluded: [marker index], out_of_view: [marker index], board_visible}"},
    "board": {"type": "object",
              "description": "pose_index, cols, rows, square_m, R (rows), t_m: x_world = R x_board + t"}
  },
  "required": ["host_ns", "probe", "indentation_m", "force_n", "markers_m", "probe_tip_m",
               "probe_axis", "probe_radius_m", "probe_shown", "shaft_markers_m",
               "shaft_marker_radius_m", "cameras"]
})";

Json vec_json(const Eigen::Vector3d& v) { return eigen_to_json(v); }

}  // namespace

const MessageSchema& sync_record_schema() {
  static const MessageSchema s{"hardcopy.SyncRecord", kSyncSchema};
  return s;
}
const MessageSchema& step_record_schema() {
  static const MessageSchema s{"hardcopy.Step", kStepSchema};
  return s;
}
const MessageSchema& event_record_schema() {
  static const MessageSchema s{"hardcopy.Event", kEventSchema};
  return s;
}
const MessageSchema& ground_truth_schema() {
  static const MessageSchema s{"hardcopy.GroundTruth", kGroundTruthSchema};
  return s;
}

std::string to_json(const SyncRecord& r) {
  Json j{{"trigger_index", r.trigger_index},
         {"edge_host_ns", r.edge_host_ns},
         {"complete", r.complete},
         {"frames", Json::object()},
         {"missing_cameras", r.missing_cameras}};
  for (const auto& [camera, frame] : r.frames) j["frames"][camera] = frame;
  if (r.ft_sequence) {
    j["ft_sequence"] = *r.ft_sequence;
    j["ft_error_ns"] = r.ft_error_ns;
    j["force_n"] = {finite_or_null(r.force_n[0]), finite_or_null(r.force_n[1]),
                    finite_or_null(r.force_n[2])};
  }
  if (r.fsr_sequence) {
    j["fsr_sequence"] = *r.fsr_sequence;
    j["fsr_error_ns"] = r.fsr_error_ns;
    j["fsr_raw"] = r.fsr_raw;
    j["fsr_force_n"] = finite_or_null(r.fsr_force_n);
  }
  return dump(j);
}

std::string to_json(const StepRecord& r) {
  Json j{{"host_ns", r.host_ns}, {"step", r.step}, {"trigger_indices", r.trigger_indices}};
  put_opt(j, "location", r.location);
  put_opt(j, "level", r.level);
  if (r.target_force_n) j["target_force_n"] = finite_or_null(*r.target_force_n);
  if (r.force_n) j["force_n"] = finite_or_null(*r.force_n);
  if (r.depth_m) j["depth_m"] = finite_or_null(*r.depth_m);
  if (r.pose) j["pose"] = pose_json(*r.pose);
  put_opt(j, "board_pose", r.board_pose);
  return dump(j);
}

std::string to_json(const EventRecord& r) {
  Json j{{"host_ns", r.host_ns}, {"kind", r.kind}, {"message", r.message}};
  put_opt(j, "detected_ns", r.detected_ns);
  put_opt(j, "stop_sent_ns", r.stop_sent_ns);
  put_opt(j, "sample_host_ns", r.sample_host_ns);
  if (r.force_n) j["force_n"] = finite_or_null(*r.force_n);
  put_opt(j, "latency_ns", r.latency_ns);
  return dump(j);
}

std::string to_json(const GroundTruthRecord& t) {
  Json j{{"host_ns", t.host_ns},
         {"probe", pose_json(t.probe)},
         {"indentation_m", finite_or_null(t.indentation_m)},
         {"force_n", finite_or_null(t.force_n)}};
  put_opt(j, "trigger_index", t.trigger_index);
  Json markers = Json::array();
  for (const Eigen::Vector3d& m : t.markers_m) markers.push_back(vec_json(m));
  j["markers_m"] = std::move(markers);
  j["probe_tip_m"] = vec_json(t.probe_tip_m);
  j["probe_axis"] = vec_json(t.probe_axis);
  j["probe_radius_m"] = t.probe_radius_m;
  j["probe_shown"] = t.probe_shown;
  j["shaft_markers_m"] = {vec_json(t.shaft_markers_m[0]), vec_json(t.shaft_markers_m[1])};
  j["shaft_marker_radius_m"] = t.shaft_marker_radius_m;
  Json cameras = Json::object();
  for (const auto& [name, c] : t.cameras)
    cameras[name] = {{"occluded", c.occluded},
                     {"out_of_view", c.out_of_view},
                     {"board_visible", c.board_visible}};
  j["cameras"] = std::move(cameras);
  if (t.board) {
    const GroundTruthRecord::Board& b = *t.board;
    j["board"] = {{"pose_index", b.pose_index}, {"cols", b.cols},
                  {"rows", b.rows},             {"square_m", b.square_m},
                  {"R", eigen_to_json(b.R)},    {"t_m", vec_json(b.t_m)}};
  }
  return dump(j);
}

Result<SyncRecord> sync_record_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.SyncRecord";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  SyncRecord s;
  HC_RETURN_IF_ERROR(r.get("trigger_index", s.trigger_index));
  HC_RETURN_IF_ERROR(r.get("edge_host_ns", s.edge_host_ns));
  HC_RETURN_IF_ERROR(r.get("complete", s.complete));
  HC_ASSIGN_OR_RETURN(const JsonNode frames, r.member("frames"));
  HC_ASSIGN_OR_RETURN(const auto entries, frames.entries());
  for (const auto& [camera, frame] : entries) HC_RETURN_IF_ERROR(frame.read(s.frames[camera]));
  HC_RETURN_IF_ERROR(r.get("missing_cameras", s.missing_cameras));
  HC_RETURN_IF_ERROR(r.optional("ft_sequence", s.ft_sequence));
  if (s.ft_sequence) {
    HC_RETURN_IF_ERROR(r.get("ft_error_ns", s.ft_error_ns));
    HC_RETURN_IF_ERROR(read_measurements(r, "force_n", s.force_n));
  }
  HC_RETURN_IF_ERROR(r.optional("fsr_sequence", s.fsr_sequence));
  if (s.fsr_sequence) {
    HC_RETURN_IF_ERROR(r.get("fsr_error_ns", s.fsr_error_ns));
    HC_RETURN_IF_ERROR(r.get("fsr_raw", s.fsr_raw));
    HC_ASSIGN_OR_RETURN(const JsonNode force, r.member("fsr_force_n"));
    HC_ASSIGN_OR_RETURN(s.fsr_force_n, force.number_or_null());
  }
  return s;
}

Result<StepRecord> step_record_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.Step";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  StepRecord s;
  HC_RETURN_IF_ERROR(r.get("host_ns", s.host_ns));
  HC_RETURN_IF_ERROR(r.get("step", s.step));
  HC_RETURN_IF_ERROR(r.get("trigger_indices", s.trigger_indices));
  HC_RETURN_IF_ERROR(r.optional("location", s.location, Bounds::non_negative()));
  HC_RETURN_IF_ERROR(r.optional("level", s.level, Bounds::non_negative()));
  HC_RETURN_IF_ERROR(r.optional("target_force_n", s.target_force_n));
  HC_RETURN_IF_ERROR(r.optional("force_n", s.force_n));
  HC_RETURN_IF_ERROR(r.optional("depth_m", s.depth_m));
  if (r.has("pose")) {
    ArmPose pose;
    HC_RETURN_IF_ERROR(read_pose(r, "pose", pose));
    s.pose = pose;
  }
  HC_RETURN_IF_ERROR(r.optional("board_pose", s.board_pose, Bounds::non_negative()));
  return s;
}

Result<EventRecord> event_record_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.Event";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  EventRecord e;
  HC_RETURN_IF_ERROR(r.get("host_ns", e.host_ns));
  HC_RETURN_IF_ERROR(r.get("kind", e.kind));
  HC_RETURN_IF_ERROR(r.get("message", e.message));
  HC_RETURN_IF_ERROR(r.optional("detected_ns", e.detected_ns));
  HC_RETURN_IF_ERROR(r.optional("stop_sent_ns", e.stop_sent_ns));
  HC_RETURN_IF_ERROR(r.optional("sample_host_ns", e.sample_host_ns));
  HC_RETURN_IF_ERROR(r.optional("force_n", e.force_n));
  HC_RETURN_IF_ERROR(r.optional("latency_ns", e.latency_ns));
  return e;
}

Result<GroundTruthRecord> ground_truth_from_json(std::string_view text) {
  constexpr std::string_view kType = "hardcopy.GroundTruth";
  HC_ASSIGN_OR_RETURN(const Json j, parse_object(text, kType));
  const JsonNode r(j, kType);
  GroundTruthRecord t;
  HC_RETURN_IF_ERROR(r.get("host_ns", t.host_ns));
  HC_RETURN_IF_ERROR(r.optional("trigger_index", t.trigger_index));
  HC_RETURN_IF_ERROR(read_pose(r, "probe", t.probe));
  HC_RETURN_IF_ERROR(r.get("indentation_m", t.indentation_m));
  HC_RETURN_IF_ERROR(r.get("force_n", t.force_n));
  HC_RETURN_IF_ERROR(r.get("markers_m", t.markers_m));
  HC_RETURN_IF_ERROR(r.get("probe_tip_m", t.probe_tip_m));
  HC_RETURN_IF_ERROR(r.get("probe_axis", t.probe_axis));
  HC_RETURN_IF_ERROR(r.get("probe_radius_m", t.probe_radius_m));
  HC_RETURN_IF_ERROR(r.get("probe_shown", t.probe_shown));
  HC_RETURN_IF_ERROR(r.get("shaft_markers_m", t.shaft_markers_m));
  HC_RETURN_IF_ERROR(r.get("shaft_marker_radius_m", t.shaft_marker_radius_m));
  HC_ASSIGN_OR_RETURN(const JsonNode cameras, r.member("cameras"));
  HC_ASSIGN_OR_RETURN(const auto entries, cameras.entries());
  for (const auto& [name, c] : entries) {
    GroundTruthRecord::Camera& cam = t.cameras[name];
    HC_RETURN_IF_ERROR(c.get("occluded", cam.occluded));
    HC_RETURN_IF_ERROR(c.get("out_of_view", cam.out_of_view));
    HC_RETURN_IF_ERROR(c.get("board_visible", cam.board_visible));
  }
  if (const std::optional<JsonNode> b = r.find("board")) {
    GroundTruthRecord::Board board;
    HC_RETURN_IF_ERROR(b->get("pose_index", board.pose_index, Bounds::non_negative()));
    HC_RETURN_IF_ERROR(b->get("cols", board.cols, Bounds::positive()));
    HC_RETURN_IF_ERROR(b->get("rows", board.rows, Bounds::positive()));
    HC_RETURN_IF_ERROR(b->get("square_m", board.square_m, Bounds::positive()));
    HC_ASSIGN_OR_RETURN(const JsonNode rows, b->member("R"));
    HC_RETURN_IF_ERROR(rows.expect_array_of(3, "rows"));
    for (std::size_t i = 0; i < 3; ++i) {
      HC_ASSIGN_OR_RETURN(const Eigen::Vector3d row, rows[i].vector<3>());
      board.R.row(static_cast<Eigen::Index>(i)) = row.transpose();
    }
    HC_RETURN_IF_ERROR(b->get("t_m", board.t_m));
    t.board = board;
  }
  return t;
}

}  // namespace hc::session
