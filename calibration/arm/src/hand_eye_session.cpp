#include "calibration/arm/hand_eye_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <numbers>

#include "common/json.h"
#include "processing/tracking/session_tracking.h"
#include "processing/tracking/tracker.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"

namespace hc::calib {
namespace {

namespace rec = hc::recording;

struct ArmSample {
  std::int64_t t_ns;
  hc::session::ArmPose pose;
};

// The simulator's true cameras (metadata "sim_cameras", rig_daemon/session/topics.h): the rig
// frame is the calibration's first camera's frame, so the true world_from_rig is that camera's
// pose.
Result<std::optional<Eigen::Isometry3d>> true_world_from_rig(const rec::McapReader& reader,
                                                             const RigCalibration& calibration) {
  std::optional<Eigen::Isometry3d> truth_x;
  if (!calibration.cameras.empty()) {
    HC_ASSIGN_OR_RETURN(std::vector<rec::Metadata> metadata, reader.read_metadata());
    for (const rec::Metadata& m : metadata) {
      if (m.name != hc::session::kMetadataSimCameras) continue;
      const auto js = m.metadata.find("json");
      if (js == m.metadata.end()) continue;
      Result<Json> j = parse_json(js->second, "sim_cameras");
      if (!j.ok() || !j->is_object()) continue;
      const auto cam = j->find(calibration.cameras.front().name);
      if (cam == j->end() || !cam->is_object()) continue;
      // A malformed record means no truth, not an error.
      Result<CameraModel> truth = camera_from_json(*cam, cam.key(), "sim_cameras");
      if (truth.ok()) truth_x = truth->camera_from_reference().inverse();
    }
  }
  return truth_x;
}

}  // namespace

Result<HandEyeSessionData> read_hand_eye_session(const std::filesystem::path& session,
                                                 const RigCalibration& calibration,
                                                 const HandEyeSessionOptions& options) {
  const std::string name = session.string();
  // Arm states and shaft-marker truth first (cheap, and a session without an arm fails fast).
  HC_ASSIGN_OR_RETURN(rec::McapReader reader, rec::McapReader::open(session));
  const rec::Channel* arm = nullptr;
  for (const auto& [id, ch] : reader.channels()) {
    const auto k = ch.metadata.find("kind");
    const auto d = ch.metadata.find("device");
    if (k == ch.metadata.end() || k->second != "arm") continue;
    if (ch.topic.size() < 6 || ch.topic.substr(ch.topic.size() - 6) != "/state") continue;
    if (!options.arm_device.empty() && (d == ch.metadata.end() || d->second != options.arm_device))
      continue;
    arm = &ch;
    break;
  }
  if (!arm)
    return invalid_argument(fmt::format(
        "{}: no arm state channel{} (hand-eye needs the arm's "
        "poses; record with the automated protocol)",
        name, options.arm_device.empty() ? "" : " of device '" + options.arm_device + "'"));
  HC_ASSIGN_OR_RETURN(const std::optional<Eigen::Isometry3d> truth_x,
                      true_world_from_rig(reader, calibration));
  std::vector<ArmSample> states;
  std::map<std::uint64_t, std::array<Eigen::Vector3d, 2>> truth;  // trigger index -> markers
  rec::ReadOptions ro;
  ro.topics = {arm->topic};
  const rec::Channel* gt = reader.find_channel(hc::session::kGroundTruthTopic);
  if (gt) ro.topics.push_back(gt->topic);
  Status error;
  HC_RETURN_IF_ERROR(reader.read_messages(ro, [&](const rec::MessageEvent& e) {
    if (e.channel->id == arm->id) {
      Result<hc::session::ArmState> s = hc::session::arm_state_from_json(
          {reinterpret_cast<const char*>(e.message.data.data()), e.message.data.size()});
      if (!s.ok()) {
        error = s.status().with_context(
            fmt::format("{}: {} sequence {}", name, arm->topic, e.message.sequence));
        return false;
      }
      states.push_back({s->host_ns, s->pose});
      return true;
    }
    Result<hc::session::GroundTruthRecord> t = hc::session::ground_truth_from_json(
        {reinterpret_cast<const char*>(e.message.data.data()), e.message.data.size()});
    if (!t.ok()) {
      error = t.status().with_context(
          fmt::format("{}: {} sequence {}", name, e.channel->topic, e.message.sequence));
      return false;
    }
    if (t->trigger_index) truth[*t->trigger_index] = t->shaft_markers_m;
    return true;
  }));
  HC_RETURN_IF_ERROR(error);
  if (states.empty())
    return invalid_argument(fmt::format("{}: {}: no arm states", name, arm->topic));
  std::stable_sort(states.begin(), states.end(),
                   [](const ArmSample& a, const ArmSample& b) { return a.t_ns < b.t_ns; });

  tracking::SessionReadOptions so;
  so.max_steps = options.max_steps;
  so.blobs.threshold = markers::ThresholdMethod::kLocalMean;
  so.blobs.local_offset = options.marker_local_offset;
  so.blobs.local_block_px = options.marker_local_block_px;
  so.blobs.min_area_px = options.min_marker_area_px;
  HC_ASSIGN_OR_RETURN(tracking::SessionDetections det,
                      tracking::read_session_detections(session, calibration, so));
  HandEyeSessionData out;
  out.truth_world_from_rig = truth_x;
  out.problem.markers = 2;
  out.steps = det.steps.size();
  bool all_by_specimen = true;
  std::optional<Eigen::Vector3d> ref_axis;
  for (const tracking::SessionStep& st : det.steps) {
    const auto it = std::upper_bound(states.begin(), states.end(), st.edge_host_ns,
                                     [](std::int64_t t, const ArmSample& a) { return t < a.t_ns; });
    if (it == states.begin()) continue;  // no arm state yet
    const hc::session::ArmPose& pose = std::prev(it)->pose;
    std::vector<Eigen::Vector3d> isolated, rest;
    // The tracker's reader sets apart the dots several times a specimen dot's area (the shaft
    // markers are such balls on a high-resolution rig): exactly two points matched from those
    // are the two markers. Otherwise (small images: the markers are not told apart by size) they
    // are the two points isolated from every other.
    const bool any_shaft = std::any_of(st.shaft_detections.begin(), st.shaft_detections.end(),
                                       [](const auto& c) { return !c.empty(); });
    if (any_shaft) {
      Result<std::vector<tracking::MatchedPoint>> shaft =
          tracking::match_views(det.cameras, st.shaft_detections);
      if (!shaft.ok()) return shaft.status().with_context(name);
      if (shaft->size() == 2) isolated = {(*shaft)[0].point_m, (*shaft)[1].point_m};
    }
    const bool by_size = isolated.size() == 2;
    tracking::FrameDetections all = st.detections;
    if (!by_size)
      for (std::size_t c = 0; c < all.size() && c < st.shaft_detections.size(); ++c)
        all[c].insert(all[c].end(), st.shaft_detections[c].begin(), st.shaft_detections[c].end());
    Result<std::vector<tracking::MatchedPoint>> pts = tracking::match_views(det.cameras, all);
    if (!pts.ok()) return pts.status().with_context(name);
    for (std::size_t a = 0; a < pts->size(); ++a) {
      if (by_size) {
        rest.push_back((*pts)[a].point_m);
        continue;
      }
      double nn = std::numeric_limits<double>::infinity();
      for (std::size_t b = 0; b < pts->size(); ++b)
        if (a != b) nn = std::min(nn, ((*pts)[a].point_m - (*pts)[b].point_m).norm());
      (nn > options.isolation_m ? isolated : rest).push_back((*pts)[a].point_m);
    }
    if (isolated.size() != 2) continue;
    if (!rest.empty()) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const auto& p : rest) c += p;
      c /= static_cast<double>(rest.size());
      if ((isolated[1] - c).norm() < (isolated[0] - c).norm()) std::swap(isolated[0], isolated[1]);
    } else {
      all_by_specimen = false;
      // Keep one labelling through the session: the shaft points the same way at every pose of
      // a 4-DOF arm, so orient each pair along the first pair's direction.
      if (!ref_axis) ref_axis = isolated[1] - isolated[0];
      if ((isolated[1] - isolated[0]).dot(*ref_axis) < 0.0) std::swap(isolated[0], isolated[1]);
    }
    const std::size_t pose_index = out.problem.world_from_tool.size();
    out.problem.world_from_tool.push_back(
        arm_pose_transform(pose.x_m, pose.y_m, pose.z_m, pose.yaw_rad));
    const auto tr = truth.find(st.trigger_index);
    for (std::size_t j = 0; j < 2; ++j) {
      out.problem.observations.push_back({pose_index, j, isolated[j]});
      if (tr != truth.end())
        out.truth_world_m.emplace_back(tr->second[j]);
      else
        out.truth_world_m.emplace_back(std::nullopt);
    }
    ++out.steps_used;
  }
  out.markers_ordered_by_specimen = all_by_specimen && out.steps_used > 0;
  return out;
}

Json HandEyeSessionResult::to_json() const {
  Json j = solution.to_json();
  j["steps"] = steps;
  j["steps_used"] = steps_used;
  if (has_truth) {
    j["truth_rms_error_m"] = truth_rms_m;
    j["truth_max_error_m"] = truth_max_m;
  }
  if (has_truth_transform) {
    j["truth_translation_error_m"] = truth_translation_error_m;
    j["truth_rotation_error_deg"] = truth_rotation_error_deg;
  }
  return j;
}

Result<HandEyeSessionResult> calibrate_hand_eye_from_session(const std::filesystem::path& session,
                                                             const RigCalibration& calibration,
                                                             const HandEyeSessionOptions& options) {
  HC_ASSIGN_OR_RETURN(HandEyeSessionData data,
                      read_hand_eye_session(session, calibration, options));
  HandEyeOptions ho = options.solver;
  ho.marker0_tool_z_m = options.marker0_tool_z_m;
  {
    // A session whose arm never turns (the automated plans press straight down at yaw 0) leaves
    // the offsets unobservable (hand_eye.h): hold marker 0 on the shaft axis, as the straight
    // probe shaft puts it, at its known distance from the tip.
    bool turns = false;
    for (const Eigen::Isometry3d& t : data.problem.world_from_tool)
      if (Eigen::AngleAxisd(data.problem.world_from_tool.front().linear().transpose() * t.linear())
              .angle() > ho.min_rotation_rad)
        turns = true;
    if (!turns && !data.problem.world_from_tool.empty() && ho.known_offsets_m.empty())
      ho.known_offsets_m = {Eigen::Vector3d(0.0, 0.0, options.marker0_tool_z_m), std::nullopt};
  }
  Result<HandEyeResult> best = solve_hand_eye(data.problem, ho);
  if (!data.markers_ordered_by_specimen && best.ok()) {
    // Without specimen dots the labels come from the first step's order. Marker 0 is the one
    // nearer the tip, i.e. lower along the tool's z. The solution's rotation does not depend on
    // the labelling (only the offsets and translation do), so check in the world frame which
    // label sits lower along tool z and swap when it is marker 1.
    double along = 0.0;
    for (std::size_t k = 0; k + 1 < data.problem.observations.size(); k += 2) {
      const auto& a0 = data.problem.observations[k];
      const auto& a1 = data.problem.observations[k + 1];
      const Eigen::Vector3d d = best->world_from_rig.linear() * (a1.p_rig_m - a0.p_rig_m);
      const Eigen::Vector3d tool_z = data.problem.world_from_tool[a0.pose].linear().col(2);
      along += (a1.marker == 1 ? 1.0 : -1.0) * d.dot(tool_z);
    }
    if (along < 0.0) {
      for (auto& o : data.problem.observations) o.marker = 1 - o.marker;
      best = solve_hand_eye(data.problem, ho);
    }
  }
  if (!best.ok())
    return best.status().with_context(fmt::format("{}: {} of {} steps had both shaft markers",
                                                  session.string(), data.steps_used, data.steps));
  HandEyeSessionResult out;
  out.solution = *best;
  out.steps = data.steps;
  out.steps_used = data.steps_used;
  double ss = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < data.problem.observations.size(); ++k) {
    if (!data.truth_world_m[k] || !data.truth_world_m[k ^ 1]) continue;
    // Against the nearer of the step's two true markers (observations come in pairs per step), so
    // the comparison does not depend on which label the solver kept.
    const Eigen::Vector3d w = out.solution.world_from_rig * data.problem.observations[k].p_rig_m;
    const double e =
        std::min((w - *data.truth_world_m[k]).norm(), (w - *data.truth_world_m[k ^ 1]).norm());
    ss += e * e;
    out.truth_max_m = std::max(out.truth_max_m, e);
    ++n;
  }
  if (n > 0) {
    out.has_truth = true;
    out.truth_rms_m = std::sqrt(ss / static_cast<double>(n));
  }
  if (data.truth_world_from_rig) {
    out.has_truth_transform = true;
    out.truth_translation_error_m =
        (out.solution.world_from_rig.translation() - data.truth_world_from_rig->translation())
            .norm();
    out.truth_rotation_error_deg =
        Eigen::AngleAxisd(out.solution.world_from_rig.linear().transpose() *
                          data.truth_world_from_rig->linear())
            .angle() *
        180.0 / std::numbers::pi;
  }
  return out;
}

}  // namespace hc::calib
