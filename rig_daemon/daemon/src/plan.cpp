#include "rig_daemon/daemon/plan.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "common/file_io.h"

namespace hc::rig {
namespace {

constexpr std::array<std::string_view, 3> kAxes{"x", "y", "z"};

Json array_json(const std::array<double, 3>& a) { return Json::array({a[0], a[1], a[2]}); }

}  // namespace

Status WorkspaceBox::read(ConfigNode node) {
  node.required("min_m", min_m);
  node.required("max_m", max_m);
  return node.status();
}

Status WorkspaceBox::validate() const {
  for (std::size_t i = 0; i < 3; ++i) {
    if (!(max_m[i] > min_m[i]))
      return invalid_argument("max_m." + std::string(kAxes[i]) + " must be greater than min_m." +
                              std::string(kAxes[i]));
  }
  return {};
}

bool WorkspaceBox::contains(const std::array<double, 3>& p_m) const {
  for (std::size_t i = 0; i < 3; ++i)
    if (!(p_m[i] >= min_m[i] && p_m[i] <= max_m[i])) return false;
  return true;
}

WorkspaceBox WorkspaceBox::intersect(const WorkspaceBox& other) const {
  WorkspaceBox out;
  for (std::size_t i = 0; i < 3; ++i) {
    out.min_m[i] = std::max(min_m[i], other.min_m[i]);
    out.max_m[i] = std::min(max_m[i], other.max_m[i]);
  }
  return out;
}

bool WorkspaceBox::empty() const {
  for (std::size_t i = 0; i < 3; ++i)
    if (!(max_m[i] >= min_m[i])) return true;
  return false;
}

Json WorkspaceBox::to_json() const {
  return Json{{"min_m", array_json(min_m)}, {"max_m", array_json(max_m)}};
}

Status TriggerSettings::read(ConfigNode node) {
  // 1 kHz is far beyond any camera the rig drives (Basler piA1600: ~35 fps) and keeps the
  // schedulers' per-edge work bounded.
  node.required("rate_hz", rate_hz, Bounds{0.0, 1000.0, true, false});
  node.optional("pulse_width_s", pulse_width_s, Bounds{1e-6, 0.1, false, false});
  return node.status();
}

Status TriggerSettings::validate() const {
  if (pulse_width_s >= 1.0 / rate_hz)
    return invalid_argument("pulse_width_s must be shorter than the trigger period 1/rate_hz");
  return {};
}

Status ProbeLocation::read(ConfigNode node) {
  node.required("position_m", position_m);
  if (node.optional("direction", direction)) {
    const double n = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                               direction[2] * direction[2]);
    if (!(n > 1e-9) || !std::isfinite(n)) {
      node.error("direction", "expected a non-zero vector [x, y, z]");
    } else {
      for (double& d : direction) d /= n;
    }
  }
  return node.status();
}

std::string_view to_string(Protocol p) {
  switch (p) {
    case Protocol::kHandHeld:
      return "hand_held";
    case Protocol::kAutomated:
      return "automated";
    case Protocol::kCalibration:
      return "calibration";
  }
  return "unknown";
}

Status Plan::read(ConfigNode node) {
  node.required("protocol", protocol,
                {{"hand_held", Protocol::kHandHeld},
                 {"automated", Protocol::kAutomated},
                 {"calibration", Protocol::kCalibration}});
  node.optional("name", name);
  node.optional("description", description);
  node.optional("specimen", specimen);
  if (!node.status().ok()) return node.status();
  if (name.empty() || name.size() > 128 ||
      !std::all_of(name.begin(), name.end(),
                   [](char c) {
                     return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' ||
                            c == '.';
                   }) ||
      name.front() == '.') {
    node.error("name", "expected 1-128 characters of [A-Za-z0-9_.-] not starting with '.'");
  }
  if (protocol == Protocol::kHandHeld) {
    HandHeldPlan& p = hand_held;
    node.required("trigger", p.trigger);
    // One hour is longer than any hand-held capture; it bounds the session size.
    node.required("duration_s", p.duration_s, Bounds{0.0, 3600.0, true, false});
    node.required("cameras", p.cameras);
    node.optional("fsr", p.fsr);
  } else if (protocol == Protocol::kCalibration) {
    CalibrationPlan& p = calibration;
    if (std::optional<ConfigNode> b = node.find("board")) {
      // Inner corners (OpenCV's pattern size); 64 bounds the rendering work per frame.
      b->required("cols", p.board_cols, Bounds::between(2, 64));
      b->required("rows", p.board_rows, Bounds::between(2, 64));
      b->required("square_m", p.square_m, Bounds{0.0, 1.0, true, false});
      b->optional("margin_squares", p.margin_squares, Bounds::between(0.0, 10.0));
    } else {
      node.error("board", "required: {cols, rows, square_m}");
    }
    // 1000 poses is far more than any calibration needs (issue 5: 30) and bounds the session.
    node.required("poses", p.poses, Bounds::between(1, 1000));
    node.optional("seed", p.seed);
    node.optional("dwell_s", p.dwell_s, Bounds::between(0.0, 60.0));
    node.optional("max_tilt_deg", p.max_tilt_deg, Bounds::between(0.0, 80.0));
    node.required("cameras", p.cameras);
    if (std::optional<ConfigNode> t = node.find("trigger")) {
      t->optional("rate_hz", p.trigger.rate_hz, Bounds{0.0, 1000.0, true, false});
      t->optional("pulse_width_s", p.trigger.pulse_width_s, Bounds{1e-6, 0.1, false, false});
    }
    node.optional("trigger_device", p.trigger_device);
    if (node.status().ok() && p.cameras.empty())
      node.error("cameras", "expected at least one camera");
  } else {
    AutomatedPlan& p = automated;
    node.required("locations", p.locations);
    node.required("force_levels_n", p.force_levels_n, Bounds{0.0, kMaxPlanForceN, true, false});
    node.required("steps", p.steps, Bounds::between(kMinSteps, kMaxSteps));
    node.optional("settle_s", p.settle_s, Bounds::between(0.0, 60.0));
    node.required("max_force_n", p.max_force_n, Bounds{0.0, kMaxPlanForceN, true, false});
    node.optional("step_m", p.step_m, Bounds{0.0, 0.01, true, false});
    node.optional("max_depth_m", p.max_depth_m, Bounds{0.0, 0.2, true, false});
    node.required("workspace", p.workspace);
    node.optional("cameras", p.cameras);
    node.optional("force_torque", p.force_torque);
    node.optional("arm", p.arm);
    node.optional("trigger_device", p.trigger_device);
    node.optional("trigger", p.trigger);
    node.optional("frames_per_step", p.frames_per_step, Bounds::between(1, 16));
    if (node.status().ok()) {
      if (p.locations.empty()) node.error("locations", "expected at least one probe location");
      if (p.locations.size() > 1000) node.error("locations", "expected at most 1000 locations");
      if (p.force_levels_n.empty())
        node.error("force_levels_n", "expected at least one force level");
      for (double f : p.force_levels_n) {
        if (f > p.max_force_n) {
          node.error("force_levels_n", "every level must be at most max_force_n (" +
                                           std::to_string(p.max_force_n) + " N)");
          break;
        }
      }
      std::optional<ConfigNode> locations = node.find("locations");
      std::optional<std::vector<ConfigNode>> items;
      if (locations) items = locations->elements();
      for (std::size_t i = 0; i < p.locations.size(); ++i) {
        if (!p.workspace.contains(p.locations[i].position_m)) {
          if (items && i < items->size())
            (*items)[i].error("position_m", "outside the plan's workspace box");
          else
            node.error("locations", "location " + std::to_string(i) + " outside the workspace");
        }
      }
    }
  }
  for (const std::string& c : protocol == Protocol::kHandHeld      ? hand_held.cameras
                              : protocol == Protocol::kCalibration ? calibration.cameras
                                                                   : automated.cameras) {
    if (c.empty()) node.error("cameras", "expected device names, got an empty one");
  }
  return node.status();
}

Json Plan::to_json() const {
  Json j{{"name", name}, {"protocol", to_string(protocol)}, {"description", description}};
  Json spec = Json::object();
  for (const auto& [k, v] : specimen) spec[k] = v;
  j["specimen"] = spec;
  if (protocol == Protocol::kHandHeld) {
    j["trigger"] = {{"rate_hz", hand_held.trigger.rate_hz},
                    {"pulse_width_s", hand_held.trigger.pulse_width_s}};
    j["duration_s"] = hand_held.duration_s;
    j["cameras"] = hand_held.cameras;
    j["fsr"] = hand_held.fsr;
  } else if (protocol == Protocol::kCalibration) {
    const CalibrationPlan& p = calibration;
    j["board"] = {{"cols", p.board_cols},
                  {"rows", p.board_rows},
                  {"square_m", p.square_m},
                  {"margin_squares", p.margin_squares}};
    j["poses"] = p.poses;
    j["seed"] = p.seed;
    j["dwell_s"] = p.dwell_s;
    j["max_tilt_deg"] = p.max_tilt_deg;
    j["cameras"] = p.cameras;
    j["trigger"] = {{"pulse_width_s", p.trigger.pulse_width_s}};
    j["trigger_device"] = p.trigger_device;
  } else {
    const AutomatedPlan& p = automated;
    Json locs = Json::array();
    for (const ProbeLocation& l : p.locations)
      locs.push_back(
          {{"position_m", array_json(l.position_m)}, {"direction", array_json(l.direction)}});
    j["locations"] = locs;
    j["force_levels_n"] = p.force_levels_n;
    j["steps"] = p.steps;
    j["settle_s"] = p.settle_s;
    j["max_force_n"] = p.max_force_n;
    j["step_m"] = p.step_m;
    j["max_depth_m"] = p.max_depth_m;
    j["workspace"] = p.workspace.to_json();
    j["cameras"] = p.cameras;
    j["force_torque"] = p.force_torque;
    j["arm"] = p.arm;
    j["trigger_device"] = p.trigger_device;
    j["trigger"] = {{"pulse_width_s", p.trigger.pulse_width_s}};
    j["frames_per_step"] = p.frames_per_step;
  }
  j["expected_triggers"] = expected_triggers();
  return j;
}

std::int64_t Plan::expected_triggers() const {
  if (protocol == Protocol::kHandHeld)
    return static_cast<std::int64_t>(std::floor(hand_held.duration_s * hand_held.trigger.rate_hz));
  if (protocol == Protocol::kCalibration) return calibration.poses;
  return static_cast<std::int64_t>(automated.locations.size() * automated.force_levels_n.size()) *
         automated.steps * automated.frames_per_step;
}

Result<Plan> parse_plan(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(Config config, parse_config(text, name));
  HC_ASSIGN_OR_RETURN(Plan plan, read_config<Plan>(config));
  plan.source_text = std::string(text);
  return plan;
}

Result<Plan> load_plan(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, kMaxConfigBytes));
  return parse_plan(text, path.string());
}

}  // namespace hc::rig
