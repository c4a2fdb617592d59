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
#include "rig_daemon/session/session_reader.h"
#include "rig_daemon/session/topics.h"
#include "session_tracking_internal.h"

namespace hc::tracking {
namespace {

// A JSON field of a metadata record: a malformed one is bad input, never an exception.
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

namespace {

// Cameras: every foxglove.RawImage channel named /<camera>/image, each in the calibration and
// each calibrated camera in the session; at least two. Into out->cameras, in calibration order.
Status match_session_cameras(const recording::McapReader& reader,
                             const RigCalibration& calibration, const std::string& name,
                             SessionDetections* out) {
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
  for (const CameraModel& c : calibration.cameras) {
    if (!session_cameras.count(c.name))
      return invalid_argument(
          fmt::format("{}: calibration camera '{}' has no channel in the session (cameras: {})",
                      name, c.name, fmt::join(session_cameras, ", ")));
    out->cameras.push_back(c);
  }
  for (const std::string& s : session_cameras)
    if (calibration.find(s) == nullptr)
      return invalid_argument(
          fmt::format("{}: session camera '{}' is not in the calibration", name, s));
  if (out->cameras.size() < 2)
    return invalid_argument(fmt::format("{}: tracking needs at least 2 calibrated cameras", name));
  return {};
}

// The session's metadata: the rig config's probe, and image sizes from its calibration record
// (checked again on every frame).
Status read_session_metadata(const recording::McapReader& reader, const std::string& name,
                             SessionDetections* out) {
  Result<std::vector<recording::Metadata>> metadata = reader.read_metadata();
  if (!metadata.ok()) return invalid_argument(metadata.status().to_string());
  for (const recording::Metadata& m : *metadata) {
    if (m.name == recording::kMetadataRigConfig) {
      auto it = m.metadata.find("yaml");
      if (it != m.metadata.end()) {
        const RigProbe probe = probe_of_rig_config(it->second);
        out->shaft_marker_distances_m = probe.shaft_marker_distances_m;
        out->probe_radius_m = probe.radius_m;
      }
      continue;
    }
    if (m.name != recording::kMetadataCalibration) continue;
    auto it = m.metadata.find("json");
    if (it == m.metadata.end()) continue;
    const Json j = Json::parse(it->second, nullptr, false);
    if (j.is_discarded() || !j.is_object()) continue;
    for (const CameraModel& c : out->cameras) {
      if (!j.contains(c.name) || !j[c.name].is_object()) continue;
      int w = 0, h = 0;
      if (get_int(j[c.name], "width", w) && get_int(j[c.name], "height", h) &&
          (w != c.width || h != c.height))
        return invalid_argument(
            fmt::format("{}: camera '{}' records {}x{} images but the calibration is for {}x{}",
                        name, c.name, w, h, c.width, c.height));
    }
  }
  return {};
}

struct Sync {
  std::int64_t edge_ns = 0;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  bool has_force = false;
};

// The session's records: sync (by trigger index), steps, ground truth (by trigger index).
struct JsonRecords {
  std::map<std::uint64_t, Sync> sync;
  std::vector<SessionStep> steps;
  std::map<std::uint64_t, session::GroundTruthRecord> truth;
};

// A step record: its first trigger index, location/level/step and the arm's pose.
Status parse_step_record(const session::StepRecord& r, const std::string& name,
                         SessionStep* st) {
  if (r.trigger_indices.empty())
    return invalid_argument(fmt::format("{}: step record without trigger_indices", name));
  st->trigger_index = r.trigger_indices.front();
  st->location = r.location.value_or(-1);
  st->level = r.level.value_or(-1);
  st->step = r.step;
  if (r.pose) st->probe_tip_m = Eigen::Vector3d(r.pose->x_m, r.pose->y_m, r.pose->z_m);
  return {};
}

Result<JsonRecords> read_json_records(const recording::McapReader& reader,
                                      const std::string& name) {
  HC_ASSIGN_OR_RETURN(
      session::SessionRecords records,
      session::read_session_records(reader, {.sync = true, .steps = true, .ground_truth = true},
                                    name));
  JsonRecords rec;
  for (const session::SyncRecord& r : records.sync) {
    Sync s;
    s.edge_ns = r.edge_host_ns;
    s.force = Eigen::Vector3d(r.force_n[0], r.force_n[1], r.force_n[2]);
    s.has_force = r.ft_sequence.has_value() && s.force.allFinite();
    rec.sync[r.trigger_index] = s;
  }
  for (const session::StepRecord& r : records.steps) {
    SessionStep st;
    HC_RETURN_IF_ERROR(parse_step_record(r, name, &st));
    rec.steps.push_back(std::move(st));
  }
  for (session::GroundTruthRecord& t : records.ground_truth)
    if (t.trigger_index) rec.truth[*t.trigger_index] = std::move(t);
  if (rec.sync.empty())
    return invalid_argument(fmt::format("{}: no /session/sync records (no trigger edges)", name));
  return rec;
}

// A step's ground truth: markers, probe tip and axis, shaft markers, occluded markers per camera.
void read_step_truth(const session::GroundTruthRecord& t, const std::vector<CameraModel>& cameras,
                     SessionStep* st) {
  if (t.markers_m.empty()) return;  // a board was shown
  st->truth_markers_m = t.markers_m;
  st->truth_probe_tip_m = t.probe_tip_m;
  st->truth_probe_axis = t.probe_axis;
  st->truth_shaft_markers_m.assign(t.shaft_markers_m.begin(), t.shaft_markers_m.end());
  st->truth_occluded.resize(cameras.size());
  for (std::size_t c = 0; c < cameras.size(); ++c)
    if (auto cam = t.cameras.find(cameras[c].name); cam != t.cameras.end())
      st->truth_occluded[c] = cam->second.occluded;
}

// The steps to track (one per sync record when the session has no step records), each with its
// trigger edge, force and ground truth, and empty per-camera detections.
Result<std::vector<SessionStep>> session_steps(JsonRecords rec, const std::string& name,
                                               const std::vector<CameraModel>& cameras,
                                               std::size_t max_steps) {
  std::vector<SessionStep> steps = std::move(rec.steps);
  if (steps.empty()) {
    for (const auto& [index, s] : rec.sync) {
      SessionStep st;
      st.trigger_index = index;
      steps.push_back(std::move(st));
    }
  }
  if (max_steps > 0 && steps.size() > max_steps) steps.resize(max_steps);
  const std::size_t nc = cameras.size();
  for (std::size_t k = 0; k < steps.size(); ++k) {
    SessionStep& st = steps[k];
    auto s = rec.sync.find(st.trigger_index);
    if (s == rec.sync.end())
      return invalid_argument(fmt::format("{}: step {} names trigger {} with no sync record", name,
                                          k, st.trigger_index));
    st.edge_host_ns = s->second.edge_ns;
    st.ft_force_n = s->second.force;
    st.has_force = s->second.has_force;
    st.detections.assign(nc, {});
    st.shaft_detections.assign(nc, {});
    st.frames_found.assign(nc, 0);
    if (auto t = rec.truth.find(st.trigger_index); t != rec.truth.end())
      read_step_truth(t->second, cameras, &st);
  }
  return steps;
}

// Marker detection in batches of frames on TBB workers while the reading thread decodes the next
// batch. Each frame's dots are split into specimen markers and the larger shaft markers.
class BatchDetector {
 public:
  BatchDetector(const SessionReadOptions& options, const std::string& name,
                const std::vector<CameraModel>& cameras, std::vector<SessionStep>* steps)
      : options_(options),
        name_(name),
        cameras_(cameras),
        steps_(*steps),
        blobs_(options.blobs),
        color_(options.color) {
    // Detected up to the shaft markers' size, then split by area (see SessionReadOptions).
    blobs_.max_area_px = std::max(blobs_.max_area_px, options.shaft_marker_max_area_px);
    if (color_)
      color_->max_area_px = std::max(color_->max_area_px, options.shaft_marker_max_area_px);
  }
  ~BatchDetector() { collect(); }  // never leave a task running on the frames it holds

  void add(PendingFrame frame) {
    batch_.push_back(std::move(frame));
    if (batch_.size() >= kBatch) flush();
  }
  // Waits for the running batch and starts the pending one.
  void flush() {
    collect();
    running_.swap(batch_);
    results_.assign(running_.size(), Result<std::vector<markers::Dot>>(internal_error("not run")));
    group_.run([this] {
      tbb::parallel_for(std::size_t{0}, running_.size(), [this](std::size_t i) {
        const auto t0 = Clock::now();
        const recording::RawImage& im = running_[i].image;
        markers::ImageView v{
            static_cast<int>(im.width), static_cast<int>(im.height),
            static_cast<std::ptrdiff_t>(im.step),
            im.encoding == "rgb8" ? markers::PixelFormat::kRgb8 : markers::PixelFormat::kMono8,
            im.data.data()};
        results_[i] = options_.color ? markers::detect_color_dots(v, *color_)
                                     : markers::detect_blobs(v, blobs_);
        detect_ns_ +=
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
      });
    });
  }
  // Waits for the running batch and files its dots under their steps.
  void collect() {
    const auto tw = Clock::now();
    group_.wait();
    wait_s_ += seconds_since(tw);
    for (std::size_t i = 0; i < running_.size(); ++i) {
      if (!results_[i].ok()) {
        error_ = results_[i].status().with_context(
            fmt::format("{}: camera '{}'", name_, cameras_[running_[i].camera].name));
        continue;
      }
      SessionStep& st = steps_[running_[i].step];
      auto& dets = st.detections[running_[i].camera];
      auto& shaft = st.shaft_detections[running_[i].camera];
      const std::vector<markers::Dot>& dots = *results_[i];
      double big = options_.color ? options_.color->max_area_px : options_.blobs.max_area_px;
      if (dots.size() >= 10) {
        std::vector<double> areas;
        for (const markers::Dot& d : dots) areas.push_back(d.area_px);
        std::nth_element(areas.begin(),
                         areas.begin() + static_cast<std::ptrdiff_t>(areas.size() / 2),
                         areas.end());
        big = std::min(big, options_.shaft_marker_area_ratio * areas[areas.size() / 2]);
      }
      for (const markers::Dot& d : dots) (d.area_px > big ? shaft : dets).push_back(d.center_px);
    }
    running_.clear();
    results_.clear();
  }
  const Status& error() const { return error_; }
  // Per-frame detection times summed (CPU-seconds); time the reading thread waited.
  double detection_s() const { return static_cast<double>(detect_ns_.load()) * 1e-9; }
  double wait_s() const { return wait_s_; }

 private:
  static constexpr std::size_t kBatch = 6;
  const SessionReadOptions& options_;
  const std::string& name_;
  const std::vector<CameraModel>& cameras_;
  std::vector<SessionStep>& steps_;
  markers::BlobOptions blobs_;
  std::optional<markers::ColorDotOptions> color_;
  std::vector<PendingFrame> batch_, running_;
  std::vector<Result<std::vector<markers::Dot>>> results_;
  tbb::task_group group_;
  std::atomic<std::int64_t> detect_ns_{0};
  double wait_s_ = 0;
  Status error_;
};

// Frames: streams the camera channels and detects markers in the first frame after each step's
// trigger edge (the last edge at or before the frame's log time).
Status detect_step_frames(const recording::McapReader& reader,
                          const std::map<std::uint64_t, Sync>& sync,
                          const SessionReadOptions& options, const std::string& name,
                          std::vector<SessionStep>* steps, SessionDetections* out) {
  const std::vector<CameraModel>& cameras = out->cameras;
  std::vector<std::int64_t> edge_times;
  std::vector<std::uint64_t> edge_index;
  for (const auto& [index, s] : sync) {
    edge_times.push_back(s.edge_ns);
    edge_index.push_back(index);
  }
  std::map<std::uint64_t, std::size_t> step_of_trigger;
  for (std::size_t k = 0; k < steps->size(); ++k) step_of_trigger[(*steps)[k].trigger_index] = k;
  std::map<std::string, std::size_t> camera_of_topic;
  recording::ReadOptions ro;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    ro.topics.push_back(session::camera_topic(cameras[c].name));
    camera_of_topic[ro.topics.back()] = c;
  }
  ro.order = recording::ReadOrder::kFile;
  std::optional<tbb::global_control> limit;
  if (options.threads > 0)
    limit.emplace(tbb::global_control::max_allowed_parallelism,
                  static_cast<std::size_t>(options.threads));
  ProgressTask task(options.progress, "detecting markers", steps->size() * cameras.size());
  const auto t_frames = Clock::now();
  Status bad;
  BatchDetector detector(options, name, cameras, steps);
  const Status read = reader.read_messages(ro, [&](const recording::MessageEvent& e) {
    const std::size_t c = camera_of_topic.at(e.channel->topic);
    const auto t = static_cast<std::int64_t>(e.message.log_time);
    auto it = std::upper_bound(edge_times.begin(), edge_times.end(), t);
    if (it == edge_times.begin()) return true;
    const std::uint64_t trig = edge_index[static_cast<std::size_t>(it - edge_times.begin() - 1)];
    auto s = step_of_trigger.find(trig);
    if (s == step_of_trigger.end() || (*steps)[s->second].frames_found[c]) return true;
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
    if (static_cast<int>(im->width) != cameras[c].width ||
        static_cast<int>(im->height) != cameras[c].height) {
      bad = invalid_argument(
          fmt::format("{}: camera '{}' frame is {}x{} but the calibration is for {}x{}", name,
                      cameras[c].name, im->width, im->height, cameras[c].width, cameras[c].height));
      return false;
    }
    (*steps)[s->second].frames_found[c] = 1;
    task.advance();
    detector.add({s->second, c, std::move(*im)});
    return true;
  });
  const double read_s = seconds_since(t_frames);
  if (read.ok() && bad.ok()) detector.flush();
  detector.collect();
  if (!read.ok()) return invalid_argument(read.to_string());
  HC_RETURN_IF_ERROR(bad);
  HC_RETURN_IF_ERROR(detector.error());
  out->times.detection_s = detector.detection_s();
  out->times.decode_s += read_s - detector.wait_s();  // this thread's reading and decoding
  out->times.frames_s = seconds_since(t_frames);
  return {};
}

}  // namespace

Result<SessionDetections> read_session_detections(const std::filesystem::path& session,
                                                  const RigCalibration& calibration,
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
  SessionDetections out;
  HC_RETURN_IF_ERROR(match_session_cameras(reader, calibration, name, &out));
  HC_RETURN_IF_ERROR(read_session_metadata(reader, name, &out));

  const auto t_json = Clock::now();
  HC_ASSIGN_OR_RETURN(JsonRecords records, read_json_records(reader, name));
  const std::map<std::uint64_t, Sync> sync = records.sync;
  HC_ASSIGN_OR_RETURN(std::vector<SessionStep> steps,
                      session_steps(std::move(records), name, out.cameras, options.max_steps));
  out.has_truth = !steps.empty() && !steps.front().truth_markers_m.empty();
  out.times.decode_s += seconds_since(t_json);

  HC_RETURN_IF_ERROR(detect_step_frames(reader, sync, options, name, &steps, &out));
  out.steps = std::move(steps);
  out.times.total_s = seconds_since(t_start);
  return out;
}

}  // namespace hc::tracking
