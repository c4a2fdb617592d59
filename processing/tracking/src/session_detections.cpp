// Reading a session's detections (read_session_detections): the rig config's probe, the sync and
// step records, the ground truth and the camera frames of the session's MCAP, with the markers
// detected in every frame.
#include "processing/tracking/session_tracking.h"

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <atomic>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "common/config.h"
#include "common/json.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/topics.h"
#include "session_tracking_internal.h"

namespace hc::tracking {
namespace {

// JSON field helpers: a malformed session message is bad input, never an exception.
bool get_vec3(const Json& j, const char* key, Eigen::Vector3d& out) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3) return false;
  for (int i = 0; i < 3; ++i) {
    if (!j[key][static_cast<std::size_t>(i)].is_number()) return false;
    out[i] = j[key][static_cast<std::size_t>(i)].get<double>();
  }
  return out.allFinite();
}
template <typename T>
bool get_int(const Json& j, const char* key, T& out) {
  if (!j.contains(key) || !j[key].is_number_integer()) return false;
  out = j[key].get<T>();
  return true;
}

struct PendingFrame {
  std::size_t step = 0;
  std::size_t camera = 0;
  recording::RawImage image;
};

}  // namespace

RigProbe probe_of_rig_config(const std::string& yaml) {
  // The simulator's default probe (rig_daemon/devices sim_scene.h ProbeLook::marker_distances_m
  // and sim_world.h WorldOptions::probe_radius_m, a library the offline tools do not link): keep
  // in step with it.
  constexpr std::array<double, 2> kSimDistances{0.06, 0.11};
  constexpr double kSimRadius = 0.005;
  RigProbe out;
  Result<Config> cfg = parse_config(yaml, "rig_config");
  if (!cfg.ok()) return out;
  bool simulated = false;
  const Status st = read_config(*cfg, [&](ConfigNode root) -> Status {
    root.allow_unknown_keys();
    if (std::optional<ConfigNode> devs = root.find("devices"))
      if (auto entries = devs->entries())
        for (auto& [name, node] : *entries) {
          node.allow_unknown_keys();
          std::string backend;
          node.optional("backend", backend);
          simulated = simulated || backend == "sim";
        }
    if (std::optional<ConfigNode> world = root.find("world")) {
      simulated = true;
      world->allow_unknown_keys();
      double r = 0;
      if (world->optional("probe_radius_m", r)) out.radius_m = r;
      if (std::optional<ConfigNode> probe = world->find("probe")) {
        probe->allow_unknown_keys();
        std::array<double, 2> d{};
        if (probe->optional("marker_distances_m", d)) out.shaft_marker_distances_m = d;
      }
    }
    return {};
  });
  if (!st.ok()) return {};
  if (const auto& d = out.shaft_marker_distances_m; d && !((*d)[0] > 0 && (*d)[1] > (*d)[0]))
    out.shaft_marker_distances_m.reset();
  if (out.radius_m && !(*out.radius_m > 0 && std::isfinite(*out.radius_m))) out.radius_m.reset();
  if (simulated) {
    if (!out.shaft_marker_distances_m) out.shaft_marker_distances_m = kSimDistances;
    if (!out.radius_m) out.radius_m = kSimRadius;
  }
  return out;
}

Result<SessionDetections> read_session_detections(const std::filesystem::path& session,
                                                  const calib::RigCalibration& calibration,
                                                  const SessionReadOptions& options) {
  const auto t_start = Clock::now();
  HC_RETURN_IF_ERROR(options.blobs.validate());
  if (options.color) HC_RETURN_IF_ERROR(options.color->validate());
  if (!(options.shaft_marker_area_ratio > 1.0) || !(options.shaft_marker_max_area_px >= 0.0))
    return invalid_argument("shaft_marker_area_ratio must be > 1, shaft_marker_max_area_px >= 0");
  Result<recording::McapReader> opened = recording::McapReader::open(session);
  if (!opened.ok()) return invalid_argument(opened.status().to_string());
  const recording::McapReader& reader = *opened;
  const std::string name = session.filename().string();

  // Cameras: every foxglove.RawImage channel named /<camera>/image.
  std::set<std::string> session_cameras;
  for (const auto& [id, ch] : reader.channels()) {
    auto s = reader.schemas().find(ch.schema_id);
    const bool image =
        s != reader.schemas().end() && s->second.name == recording::kRawImageSchemaName;
    if (!image) continue;
    const std::string& t = ch.topic;
    if (t.size() > 7 && t.front() == '/' && t.ends_with("/image"))
      session_cameras.insert(t.substr(1, t.size() - 7));
  }
  if (session_cameras.empty())
    return invalid_argument(
        fmt::format("{}: the session has no camera channel (/<camera>/image)", name));
  SessionDetections out;
  for (const calib::CameraModel& c : calibration.cameras) {
    if (!session_cameras.count(c.name))
      return invalid_argument(
          fmt::format("{}: calibration camera '{}' has no channel in the session (cameras: {})",
                      name, c.name, fmt::join(session_cameras, ", ")));
    out.cameras.push_back(c);
  }
  for (const std::string& s : session_cameras)
    if (calibration.find(s) == nullptr)
      return invalid_argument(
          fmt::format("{}: session camera '{}' is not in the calibration", name, s));
  if (out.cameras.size() < 2)
    return invalid_argument(fmt::format("{}: tracking needs at least 2 calibrated cameras", name));
  const std::size_t nc = out.cameras.size();

  // Image sizes from the session's calibration metadata (checked again on every frame).
  Result<std::vector<recording::Metadata>> metadata = reader.read_metadata();
  if (!metadata.ok()) return invalid_argument(metadata.status().to_string());
  for (const recording::Metadata& m : *metadata) {
    if (m.name == recording::kMetadataRigConfig) {
      auto it = m.metadata.find("yaml");
      if (it != m.metadata.end()) {
        const RigProbe probe = probe_of_rig_config(it->second);
        out.shaft_marker_distances_m = probe.shaft_marker_distances_m;
        out.probe_radius_m = probe.radius_m;
      }
      continue;
    }
    if (m.name != recording::kMetadataCalibration) continue;
    auto it = m.metadata.find("json");
    if (it == m.metadata.end()) continue;
    const Json j = Json::parse(it->second, nullptr, false);
    if (j.is_discarded() || !j.is_object()) continue;
    for (const calib::CameraModel& c : out.cameras) {
      if (!j.contains(c.name) || !j[c.name].is_object()) continue;
      int w = 0, h = 0;
      if (get_int(j[c.name], "width", w) && get_int(j[c.name], "height", h) &&
          (w != c.width || h != c.height))
        return invalid_argument(
            fmt::format("{}: camera '{}' records {}x{} images but the calibration is for {}x{}",
                        name, c.name, w, h, c.width, c.height));
    }
  }

  // The JSON channels.
  const auto t_json = Clock::now();
  struct Sync {
    std::int64_t edge_ns = 0;
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    bool has_force = false;
  };
  std::map<std::uint64_t, Sync> sync;
  std::vector<SessionStep> steps;
  std::map<std::uint64_t, Json> truth;
  Status bad;
  recording::ReadOptions ro;
  ro.topics = {std::string(session::kSyncTopic), std::string(session::kStepsTopic),
               std::string(session::kGroundTruthTopic)};
  ro.order = recording::ReadOrder::kLogTime;
  Status read = reader.read_messages(ro, [&](const recording::MessageEvent& e) {
    Result<Json> j = recording::parse_json_message(e.message.data);
    if (!j.ok() || !j->is_object()) {
      bad = invalid_argument(fmt::format("{}: {} message {} is not a JSON object", name,
                                         e.channel->topic, e.message.sequence));
      return false;
    }
    const std::string& topic = e.channel->topic;
    if (topic == session::kSyncTopic) {
      std::uint64_t index = 0;
      Sync s;
      if (!get_int(*j, "trigger_index", index) || !get_int(*j, "edge_host_ns", s.edge_ns)) {
        bad = invalid_argument(
            fmt::format("{}: sync record without trigger_index/edge_host_ns", name));
        return false;
      }
      s.has_force = get_vec3(*j, "force_n", s.force);
      sync[index] = s;
    } else if (topic == session::kStepsTopic) {
      SessionStep st;
      if (!j->contains("trigger_indices") || !(*j)["trigger_indices"].is_array() ||
          (*j)["trigger_indices"].empty() || !(*j)["trigger_indices"][0].is_number_integer()) {
        bad = invalid_argument(fmt::format("{}: step record without trigger_indices", name));
        return false;
      }
      st.trigger_index = (*j)["trigger_indices"][0].get<std::uint64_t>();
      get_int(*j, "location", st.location);
      get_int(*j, "level", st.level);
      get_int(*j, "step", st.step);
      if (j->contains("pose") && (*j)["pose"].is_object()) {
        const Json& p = (*j)["pose"];
        if (p.contains("x_m") && p["x_m"].is_number() && p.contains("y_m") &&
            p["y_m"].is_number() && p.contains("z_m") && p["z_m"].is_number())
          st.probe_tip_m = Eigen::Vector3d(p["x_m"].get<double>(), p["y_m"].get<double>(),
                                           p["z_m"].get<double>());
      }
      steps.push_back(std::move(st));
    } else {
      std::uint64_t index = 0;
      if (get_int(*j, "trigger_index", index)) truth[index] = std::move(*j);
    }
    return true;
  });
  if (!read.ok()) return invalid_argument(read.to_string());
  HC_RETURN_IF_ERROR(bad);
  if (sync.empty())
    return invalid_argument(fmt::format("{}: no /session/sync records (no trigger edges)", name));
  if (steps.empty()) {
    for (const auto& [index, s] : sync) {
      SessionStep st;
      st.trigger_index = index;
      steps.push_back(std::move(st));
    }
  }
  if (options.max_steps > 0 && steps.size() > options.max_steps) steps.resize(options.max_steps);
  std::vector<std::int64_t> edge_times;
  std::vector<std::uint64_t> edge_index;
  for (const auto& [index, s] : sync) {
    edge_times.push_back(s.edge_ns);
    edge_index.push_back(index);
  }
  std::map<std::uint64_t, std::size_t> step_of_trigger;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    SessionStep& st = steps[k];
    auto s = sync.find(st.trigger_index);
    if (s == sync.end())
      return invalid_argument(fmt::format("{}: step {} names trigger {} with no sync record", name,
                                          k, st.trigger_index));
    st.edge_host_ns = s->second.edge_ns;
    st.ft_force_n = s->second.force;
    st.has_force = s->second.has_force;
    st.detections.assign(nc, {});
    st.shaft_detections.assign(nc, {});
    st.frames_found.assign(nc, 0);
    step_of_trigger[st.trigger_index] = k;
    auto t = truth.find(st.trigger_index);
    if (t != truth.end() && t->second.contains("markers_m") && t->second["markers_m"].is_array()) {
      for (const Json& m : t->second["markers_m"]) {
        if (!m.is_array() || m.size() != 3 || !m[0].is_number() || !m[1].is_number() ||
            !m[2].is_number())
          return invalid_argument(fmt::format("{}: ground truth markers_m malformed", name));
        st.truth_markers_m.emplace_back(m[0].get<double>(), m[1].get<double>(), m[2].get<double>());
      }
      Eigen::Vector3d v;
      if (get_vec3(t->second, "probe_tip_m", v)) st.truth_probe_tip_m = v;
      if (get_vec3(t->second, "probe_axis", v)) st.truth_probe_axis = v;
      if (t->second.contains("shaft_markers_m") && t->second["shaft_markers_m"].is_array())
        for (const Json& m : t->second["shaft_markers_m"]) {
          if (!m.is_array() || m.size() != 3 || !m[0].is_number() || !m[1].is_number() ||
              !m[2].is_number())
            return invalid_argument(
                fmt::format("{}: ground truth shaft_markers_m malformed", name));
          st.truth_shaft_markers_m.emplace_back(m[0].get<double>(), m[1].get<double>(),
                                                m[2].get<double>());
        }
      if (t->second.contains("cameras") && t->second["cameras"].is_object()) {
        st.truth_occluded.resize(nc);
        for (std::size_t c = 0; c < nc; ++c) {
          const Json& cams = t->second["cameras"];
          if (!cams.contains(out.cameras[c].name)) continue;
          const Json& cj = cams[out.cameras[c].name];
          if (cj.is_object() && cj.contains("occluded") && cj["occluded"].is_array())
            for (const Json& i : cj["occluded"])
              if (i.is_number_unsigned()) st.truth_occluded[c].push_back(i.get<std::uint32_t>());
        }
      }
    }
  }
  out.has_truth = !steps.empty() && !steps.front().truth_markers_m.empty();
  out.times.decode_s += seconds_since(t_json);

  // Frames: stream the camera channels, keep the frame after each step's edge, detect in batches.
  std::map<std::string, std::size_t> camera_of_topic;
  std::vector<std::string> topics;
  for (std::size_t c = 0; c < nc; ++c) {
    topics.push_back(session::camera_topic(out.cameras[c].name));
    camera_of_topic[topics.back()] = c;
  }
  std::optional<tbb::global_control> limit;
  if (options.threads > 0)
    limit.emplace(tbb::global_control::max_allowed_parallelism,
                  static_cast<std::size_t>(options.threads));
  // Decoding (this thread) overlaps detection (TBB workers): while one batch of frames is being
  // detected, the next is decoded. detection_s sums the per-frame detection times (CPU-seconds).
  // Detected up to the shaft markers' size, then split by area (see SessionReadOptions).
  markers::BlobOptions blobs = options.blobs;
  blobs.max_area_px = std::max(blobs.max_area_px, options.shaft_marker_max_area_px);
  std::optional<markers::ColorDotOptions> color = options.color;
  if (color) color->max_area_px = std::max(color->max_area_px, options.shaft_marker_max_area_px);
  std::vector<PendingFrame> batch, running;
  std::vector<Result<std::vector<markers::Dot>>> running_results;
  constexpr std::size_t kBatch = 6;
  Status detect_error;
  std::atomic<std::int64_t> detect_ns{0};
  tbb::task_group group;
  double wait_s = 0;  // this thread blocked on detection
  const auto collect = [&] {
    const auto tw = Clock::now();
    group.wait();
    wait_s += seconds_since(tw);
    for (std::size_t i = 0; i < running.size(); ++i) {
      if (!running_results[i].ok()) {
        detect_error = running_results[i].status().with_context(
            fmt::format("{}: camera '{}'", name, out.cameras[running[i].camera].name));
        continue;
      }
      SessionStep& st = steps[running[i].step];
      auto& dets = st.detections[running[i].camera];
      auto& shaft = st.shaft_detections[running[i].camera];
      const std::vector<markers::Dot>& dots = *running_results[i];
      double big = options.color ? options.color->max_area_px : options.blobs.max_area_px;
      if (dots.size() >= 10) {
        std::vector<double> areas;
        for (const markers::Dot& d : dots) areas.push_back(d.area_px);
        std::nth_element(areas.begin(),
                         areas.begin() + static_cast<std::ptrdiff_t>(areas.size() / 2),
                         areas.end());
        big = std::min(big, options.shaft_marker_area_ratio * areas[areas.size() / 2]);
      }
      for (const markers::Dot& d : dots) (d.area_px > big ? shaft : dets).push_back(d.center_px);
    }
    running.clear();
    running_results.clear();
  };
  const auto flush = [&] {
    collect();
    running.swap(batch);
    running_results.assign(running.size(),
                           Result<std::vector<markers::Dot>>(internal_error("not run")));
    group.run([&] {
      tbb::parallel_for(std::size_t{0}, running.size(), [&](std::size_t i) {
        const auto t0 = Clock::now();
        const recording::RawImage& im = running[i].image;
        markers::ImageView v{
            static_cast<int>(im.width), static_cast<int>(im.height),
            static_cast<std::ptrdiff_t>(im.step),
            im.encoding == "rgb8" ? markers::PixelFormat::kRgb8 : markers::PixelFormat::kMono8,
            im.data.data()};
        running_results[i] =
            options.color ? markers::detect_color_dots(v, *color) : markers::detect_blobs(v, blobs);
        detect_ns +=
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
      });
    });
  };
  ro.topics = topics;
  ro.order = recording::ReadOrder::kFile;
  ProgressTask task(options.progress, "detecting markers", steps.size() * nc);
  const auto t_frames = Clock::now();
  read = reader.read_messages(ro, [&](const recording::MessageEvent& e) {
    const std::size_t c = camera_of_topic.at(e.channel->topic);
    // The edge this frame follows: the last edge at or before its log time.
    const auto t = static_cast<std::int64_t>(e.message.log_time);
    auto it = std::upper_bound(edge_times.begin(), edge_times.end(), t);
    if (it == edge_times.begin()) return true;
    const std::uint64_t trig = edge_index[static_cast<std::size_t>(it - edge_times.begin() - 1)];
    auto s = step_of_trigger.find(trig);
    if (s == step_of_trigger.end() || steps[s->second].frames_found[c]) return true;
    Result<recording::RawImage> im = recording::decode_raw_image(e.message.data);
    if (!im.ok()) {
      bad = invalid_argument(fmt::format("{}: {} frame {}: {}", name, e.channel->topic,
                                         e.message.sequence, im.status().to_string()));
      return false;
    }
    if (im->encoding != "mono8" && im->encoding != "rgb8") {
      bad = invalid_argument(fmt::format("{}: {}: unsupported image encoding '{}'", name,
                                         e.channel->topic, im->encoding));
      return false;
    }
    if (static_cast<int>(im->width) != out.cameras[c].width ||
        static_cast<int>(im->height) != out.cameras[c].height) {
      bad = invalid_argument(fmt::format(
          "{}: camera '{}' frame is {}x{} but the calibration is for {}x{}", name,
          out.cameras[c].name, im->width, im->height, out.cameras[c].width, out.cameras[c].height));
      return false;
    }
    steps[s->second].frames_found[c] = 1;
    task.advance();
    batch.push_back({s->second, c, std::move(*im)});
    if (batch.size() >= kBatch) flush();
    return true;
  });
  const double read_s = seconds_since(t_frames);
  if (read.ok() && bad.ok()) flush();
  collect();  // never leave a task running on this frame's locals
  if (!read.ok()) return invalid_argument(read.to_string());
  HC_RETURN_IF_ERROR(bad);
  HC_RETURN_IF_ERROR(detect_error);
  out.times.detection_s = static_cast<double>(detect_ns.load()) * 1e-9;
  out.times.decode_s += read_s - wait_s;  // this thread's reading and decoding
  out.times.frames_s = seconds_since(t_frames);
  out.steps = std::move(steps);
  out.times.total_s = seconds_since(t_start);
  return out;
}

}  // namespace hc::tracking
