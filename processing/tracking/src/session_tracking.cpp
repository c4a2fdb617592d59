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

namespace hc::tracking {
namespace {

using Clock = std::chrono::steady_clock;
// The median over the points of the distance to the nearest other point (0 for fewer than two).
double median_neighbour_distance(const std::vector<Eigen::Vector3d>& p) {
  if (p.size() < 2) return 0;
  std::vector<double> d(p.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      const double dij = (p[i] - p[j]).norm();
      d[i] = std::min(d[i], dij);
      d[j] = std::min(d[j], dij);
    }
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

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

// Nodes on the boundary of a tet mesh: those of faces that belong to one tet only.
std::vector<std::uint8_t> boundary_nodes(const TetMesh& mesh) {
  std::vector<std::array<int, 4>> faces;  // sorted face nodes + tet (for stable sort)
  faces.reserve(static_cast<std::size_t>(mesh.num_tets()) * 4);
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 4> f{};
      int k = 0;
      for (int i = 0; i < 4; ++i)
        if (i != skip) f[static_cast<std::size_t>(k++)] = mesh.tets(t, i);
      std::sort(f.begin(), f.begin() + 3);
      f[3] = 0;
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end());
  std::vector<std::uint8_t> on(static_cast<std::size_t>(mesh.num_nodes()), 0);
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1)
      for (int k = 0; k < 3; ++k)
        on[static_cast<std::size_t>(faces[i][static_cast<std::size_t>(k)])] = 1;
    i = j;
  }
  return on;
}

// The probe sphere as a constraint of the occlusion fill (template frame). A smooth fill of the
// visible markers' displacements misses the dimple the sphere presses: the visible markers around
// it moved less than the hidden ones under it, and a biharmonic interpolant through a deep point
// under the tip and shallow ones around it overshoots below the sphere near the contact's edge
// (a whole 30-step press reached 0.7 mm there). So the sphere cap over the contact patch is a
// constraint of its own (below), and two rules are applied to the current fill, which is solved
// again with the resulting points as constraints (3 passes: the contact set settles):
//  * any filled point inside the sphere is moved onto it (along the push direction): the
//    specimen cannot enter the probe;
//  * a filled surface node within the contact radius a of the probe's axis is put on the sphere
//    wherever the fill left it: inside the contact patch the surface takes the indenter's shape.
//    For a sphere of radius R pressed to depth d into an elastic body, a = sqrt(R d) (Hertz
//    contact: K. L. Johnson, Contact Mechanics, 1985, Sec. 4.2, d = a^2 / R); d is the depth of
//    the tip below the rest surface there (the rest surface nodes nearest the axis, weighted by
//    inverse lateral distance).
std::vector<Eigen::Vector3d> fill_with_probe_contact(
    const std::vector<Eigen::Vector3d>& known_p, const std::vector<Eigen::Vector3d>& known_d,
    const std::vector<Eigen::Vector3d>& query, const std::vector<std::uint8_t>& query_on_surface,
    const std::vector<Eigen::Vector3d>& surface_nodes, const Eigen::Vector3d& tip,
    const Eigen::Vector3d& down, const SessionTrackOptions& options,
    std::vector<Eigen::Vector3d> filled) {
  const double R = *options.probe_radius_m;
  const Eigen::Vector3d centre = tip - R * down;
  const auto lateral = [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3d w = x - tip;
    return Eigen::Vector3d(w - w.dot(down) * down);
  };
  // The rest surface along the axis at lateral offset l from the tip: axial position (along
  // `down`, from the tip) interpolated from the nearest rest surface nodes (inverse lateral
  // distance weights; nodes farther than 2 R along the axis are the specimen's other side).
  const auto rest_axial = [&](const Eigen::Vector3d& l, double* out) {
    std::vector<std::pair<double, double>> near;  // lateral distance, axial position
    for (const Eigen::Vector3d& p : surface_nodes) {
      const double s = (p - tip).dot(down);
      if (std::abs(s) > 2.0 * R) continue;
      near.emplace_back((lateral(p) - l).norm(), s);
    }
    const std::size_t k = std::min<std::size_t>(4, near.size());
    if (k == 0) return false;
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
    double ws = 0.0, ss = 0.0;
    for (std::size_t i = 0; i < k; ++i) {
      const double w = 1.0 / std::max(near[i].first, 1e-6);
      ws += w;
      ss += w * near[i].second;
    }
    *out = ss / ws;
    return true;
  };
  double s_tip = 0.0;
  if (!rest_axial(Eigen::Vector3d::Zero(), &s_tip)) return filled;
  const double depth = -s_tip;  // the tip below the rest surface: > 0
  const double contact_radius = depth > 0 ? std::sqrt(R * std::min(depth, R)) : 0.0;
  // The contact patch as constraints of its own: points of the sphere cap at the tip and on rings
  // of radius a / 2 and a (8 each), with rest positions straight above them on the rest surface
  // (their lateral displacement, (1 - 2 nu) times smaller, is neglected). Without them the
  // interpolant between a measured deep point under the tip and the shallow markers around
  // overshoots below the sphere near the patch's edge. A patch point nearer than a / 4 to a
  // measured marker is left out (the measurement decides there).
  std::vector<Eigen::Vector3d> base_p = known_p, base_d = known_d;
  if (contact_radius > 0) {
    const Eigen::Vector3d e1 = down.unitOrthogonal(), e2 = down.cross(e1);
    std::vector<Eigen::Vector3d> lat{Eigen::Vector3d::Zero()};
    for (double f : {0.5, 1.0})
      for (int i = 0; i < 8; ++i) {
        const double t = M_PI * i / 4.0;
        lat.push_back(f * contact_radius * (std::cos(t) * e1 + std::sin(t) * e2));
      }
    for (const Eigen::Vector3d& l : lat) {
      double s_rest = 0.0;
      if (!rest_axial(l, &s_rest)) continue;
      const Eigen::Vector3d rest = tip + l + s_rest * down;
      const Eigen::Vector3d on = centre + l + std::sqrt(R * R - l.squaredNorm()) * down;
      bool near_known = false;
      for (const Eigen::Vector3d& p : known_p)
        near_known = near_known || (p - rest).norm() < 0.25 * contact_radius;
      if (near_known) continue;
      base_p.push_back(rest);
      base_d.push_back(on - rest);
    }
    if (base_p.size() > known_p.size())
      filled = interpolate_displacements(base_p, base_d, query, options.fill_regularization_m);
  }
  for (int pass = 0; pass < 3; ++pass) {
    std::vector<Eigen::Vector3d> cp = base_p, cd = base_d;
    std::size_t contacts = 0;
    for (std::size_t q = 0; q < query.size(); ++q) {
      const Eigen::Vector3d x = query[q] + filled[q];
      const Eigen::Vector3d l = lateral(x);
      const double rho = l.norm();
      if (rho >= R) continue;
      // The sphere's lower surface at this lateral position.
      const Eigen::Vector3d on = centre + l + std::sqrt(R * R - rho * rho) * down;
      const bool inside = (x - centre).norm() < R;
      // A surface node under the probe (not the far side of a thin specimen).
      const bool in_patch =
          query_on_surface[q] && rho <= contact_radius && std::abs((x - on).dot(down)) < R;
      if (!inside && !in_patch) continue;
      cp.push_back(query[q]);
      cd.push_back(on - query[q]);
      ++contacts;
    }
    if (contacts == 0) break;
    filled = interpolate_displacements(cp, cd, query, options.fill_regularization_m);
  }
  return filled;
}

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

struct PendingFrame {
  std::size_t step = 0;
  std::size_t camera = 0;
  recording::RawImage image;
};

}  // namespace

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

std::optional<ProbePose> probe_pose_from_shaft_markers(
    const std::vector<calib::CameraModel>& cameras, const FrameDetections& shaft_detections,
    const Eigen::Isometry3d& world_from_rig, const std::array<double, 2>& distances_m,
    const std::vector<Eigen::Vector3d>& specimen_world, const ProbePoseOptions& options) {
  if (shaft_detections.size() != cameras.size()) return std::nullopt;
  std::size_t seen = 0;
  for (const auto& d : shaft_detections) seen += d.empty() ? 0 : 1;
  if (seen < 2) return std::nullopt;
  Result<std::vector<MatchedPoint>> pts = match_views(cameras, shaft_detections, options.match);
  if (!pts.ok() || pts->size() < 2) return std::nullopt;
  const double spacing = distances_m[1] - distances_m[0];
  double best = options.distance_tolerance_m;
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pair;
  for (std::size_t i = 0; i < pts->size(); ++i)
    for (std::size_t j = i + 1; j < pts->size(); ++j) {
      const Eigen::Vector3d a = world_from_rig * (*pts)[i].point_m;
      const Eigen::Vector3d b = world_from_rig * (*pts)[j].point_m;
      const double e = std::abs((a - b).norm() - spacing);
      if (e <= best) {
        best = e;
        pair = std::make_pair(a, b);
      }
    }
  if (!pair) return std::nullopt;
  // Marker 0 is the one nearer the specimen (the tip end of the shaft).
  const auto nearest = [&](const Eigen::Vector3d& x) {
    double d = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : specimen_world) d = std::min(d, (p - x).squaredNorm());
    return d;
  };
  if (nearest(pair->second) < nearest(pair->first)) std::swap(pair->first, pair->second);
  ProbePose pose;
  pose.from_markers = true;
  pose.markers_m = {pair->first, pair->second};
  pose.axis = (pair->second - pair->first).normalized();
  pose.tip_m = pair->first - distances_m[0] * pose.axis;
  return pose;
}

Result<TrackedSession> track_detections(const SessionDetections& in,
                                        const calib::RigCalibration& calibration,
                                        const TetMesh& mesh, const SessionTrackOptions& requested) {
  HC_RETURN_IF_ERROR(requested.track.validate());
  // The probe radius: the caller's, else the session's, else the simulator's default.
  SessionTrackOptions options = requested;
  if (!options.probe_radius_m) options.probe_radius_m = in.probe_radius_m.value_or(0.005);
  if (!(*options.probe_radius_m > 0) || !std::isfinite(*options.probe_radius_m))
    return invalid_argument("the probe radius must be > 0");
  if (in.steps.empty()) return invalid_argument("no steps to track");
  if (mesh.num_nodes() < 4 || mesh.num_tets() < 1)
    return invalid_argument("the template mesh is empty");
  TrackedSession out;
  TrackSummary& sum = out.summary;
  sum.times = in.times;
  const std::size_t nc = in.cameras.size();

  // ---- Tracking ----
  auto t0 = Clock::now();
  MarkerTracker tracker(in.cameras, options.track);
  std::vector<StepResult> results;
  results.reserve(in.steps.size());
  for (std::size_t k = 0; k < in.steps.size(); ++k) {
    Result<StepResult> r =
        k == 0 ? tracker.initialise(in.steps[k].detections) : tracker.track(in.steps[k].detections);
    if (!r.ok()) return r.status().with_context(fmt::format("step {}", k));
    results.push_back(std::move(*r));
  }
  sum.times.matching_s = seconds_since(t0);
  // Markers found in later steps: unmeasured in the steps before.
  for (StepResult& r : results) {
    r.points_m.resize(tracker.num_markers(), Eigen::Vector3d::Zero());
    r.measured.resize(tracker.num_markers(), 0);
    r.views.resize(tracker.num_markers(), 0);
  }
  if (tracker.num_markers() < 4)
    return failed_precondition(
        fmt::format("only {} markers found in the first step (need >= 4 in >= {} cameras)",
                    tracker.num_markers(), options.track.match.min_views));

  // ---- Registration to the template ----
  t0 = Clock::now();
  const auto nm = tracker.num_markers();
  const std::vector<int>& birth = tracker.birth_step();
  const std::size_t n0 = results[0].points_m.size();  // markers of the first step
  // A marker's position in its birth step (measured there by construction).
  const auto birth_point = [&](std::size_t m) {
    return results[static_cast<std::size_t>(birth[m])].points_m[m];
  };
  std::vector<Eigen::Vector3d> first_world(n0);
  for (std::size_t m = 0; m < n0; ++m)
    first_world[m] = calibration.world_from_rig * results[0].points_m[m];
  std::vector<Eigen::Vector3d> nodes(static_cast<std::size_t>(mesh.num_nodes()));
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    nodes[static_cast<std::size_t>(i)] = mesh.nodes.row(i).transpose();
  Result<IcpResult> reg =
      icp(first_world, nodes, Eigen::Isometry3d::Identity(), options.template_match_distance_m);
  if (!reg.ok())
    return failed_precondition(
        fmt::format("registration of the markers to the template failed: {} (is the template in "
                    "the world frame of the calibration?)",
                    reg.status().message()));
  sum.registration_rms_m = reg->rms_m;
  if (reg->rms_m > options.max_registration_rms_m) {
    std::vector<Eigen::Vector3d> matched_nodes;
    for (const int n : reg->match)
      if (n >= 0) matched_nodes.push_back(nodes[static_cast<std::size_t>(n)]);
    return failed_precondition(fmt::format(
        "the markers do not sit on the template's nodes: after registration they are {:.2f} mm "
        "from their nodes (RMS; limit {:.2f} mm), and that offset would be in every displacement. "
        "The markers are {:.2f} mm apart, the nodes they meet {:.2f} mm: make a template "
        "whose surface nodes are markers (e.g. `hardcopy tetmesh --box` with a cell size that is a "
        "whole multiple of the marker spacing), or raise the limit (--max-registration-rms) if "
        "the markers were placed by hand",
        1e3 * reg->rms_m, 1e3 * options.max_registration_rms_m,
        1e3 * median_neighbour_distance(first_world),
        1e3 * median_neighbour_distance(matched_nodes)));
  }
  const Eigen::Isometry3d T_tpl_rig = reg->T * calibration.world_from_rig;
  // Markers farther than the match distance from their node (deformed in their first step, or
  // found in a later step) are assigned by their estimated rest position: their position minus
  // the displacement interpolated from the markers already assigned and measured in that step,
  // nearest free node first.
  std::vector<int> node_of(nm, -1);
  std::vector<int> marker_of_node(nodes.size(), -1);
  for (std::size_t m = 0; m < n0; ++m)
    if (reg->match[m] >= 0) {
      node_of[m] = reg->match[m];
      marker_of_node[static_cast<std::size_t>(reg->match[m])] = static_cast<int>(m);
    }
  for (std::size_t k = 0; k < results.size(); ++k) {
    const StepResult& r = results[k];
    for (int round = 0; round < 3; ++round) {
      std::vector<Eigen::Vector3d> kp, kd, q;
      std::vector<std::size_t> qm;
      for (std::size_t m = 0; m < r.points_m.size(); ++m) {
        const Eigen::Vector3d x = T_tpl_rig * r.points_m[m];
        if (node_of[m] >= 0 && r.measured[m]) {
          kp.push_back(x);
          kd.push_back(x - nodes[static_cast<std::size_t>(node_of[m])]);
        } else if (node_of[m] < 0 && birth[m] == static_cast<int>(k)) {
          q.push_back(x);
          qm.push_back(m);
        }
      }
      if (q.empty() || kp.size() < 4) break;
      const std::vector<Eigen::Vector3d> d = interpolate_displacements(kp, kd, q);
      std::vector<std::tuple<double, std::size_t, std::size_t>> cand;  // distance, marker, node
      for (std::size_t i = 0; i < q.size(); ++i) {
        const Eigen::Vector3d rest = q[i] - d[i];
        for (std::size_t n = 0; n < nodes.size(); ++n) {
          if (marker_of_node[n] >= 0) continue;
          const double dist = (nodes[n] - rest).norm();
          if (dist <= options.template_match_distance_m) cand.emplace_back(dist, qm[i], n);
        }
      }
      std::sort(cand.begin(), cand.end());
      std::size_t added = 0;
      for (const auto& [dist, m, n] : cand) {
        if (node_of[m] >= 0 || marker_of_node[n] >= 0) continue;
        node_of[m] = static_cast<int>(n);
        marker_of_node[n] = static_cast<int>(m);
        ++added;
      }
      if (added == 0) break;
    }
  }
  std::vector<std::size_t> kept;  // tracked marker ids registered to a node
  for (std::size_t m = 0; m < nm; ++m)
    if (node_of[m] >= 0) {
      kept.push_back(m);
      out.marker_node.push_back(node_of[m]);
    }
  sum.markers = kept.size();
  sum.steps = in.steps.size();
  if (kept.size() < 4)
    return failed_precondition(fmt::format("only {} markers lie within {} m of a template node",
                                           kept.size(), options.template_match_distance_m));

  // Fixed nodes: the template's bottom.
  const double zmin = mesh.nodes.col(2).minCoeff();
  std::vector<int> fixed;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    if (mesh.nodes(i, 2) <= zmin + options.fixed_tolerance_m) fixed.push_back(static_cast<int>(i));
  const std::vector<std::uint8_t> on_surface = boundary_nodes(mesh);
  std::vector<Eigen::Vector3d> surface_nodes;  // rest positions, for the probe's indentation
  for (std::size_t n = 0; n < nodes.size(); ++n)
    if (on_surface[n]) surface_nodes.push_back(nodes[n]);

  out.samples.mesh = mesh;
  const Eigen::Matrix3d R_tpl_world = reg->T.linear();
  std::size_t measured_pairs = 0, matched_dets = 0, all_dets = 0;
  // Truth bookkeeping: tracked marker -> truth index by the first step.
  std::vector<int> truth_of(nm, -1);
  if (in.has_truth) {
    for (std::size_t m = 0; m < nm; ++m) {
      const auto& tm = in.steps[static_cast<std::size_t>(birth[m])].truth_markers_m;
      const Eigen::Vector3d xw = calibration.world_from_rig * birth_point(m);
      double best = 1e-3;
      for (std::size_t i = 0; i < tm.size(); ++i) {
        const double d = (tm[i] - xw).norm();
        if (d < best) {
          best = d;
          truth_of[m] = static_cast<int>(i);
        }
      }
    }
  }
  double t_ss = 0, t_max = 0, f_ss = 0, f_max = 0, p_ss = 0;
  std::size_t t_n = 0, f_n = 0, t_visible = 0, t_measured = 0, p_n = 0;
  const std::optional<std::array<double, 2>> shaft_distances =
      options.probe.shaft_marker_distances_m ? options.probe.shaft_marker_distances_m
                                             : in.shaft_marker_distances_m;

  for (std::size_t k = 0; k < in.steps.size(); ++k) {
    const SessionStep& st = in.steps[k];
    const StepResult& r = results[k];
    all_dets += r.detections;
    matched_dets += r.matched_detections;
    // The probe's pose: from the shaft markers, else the arm's reported pose (world frame).
    std::optional<ProbePose> probe;
    if (options.probe_from_shaft_markers && shaft_distances) {
      std::vector<Eigen::Vector3d> specimen;
      for (std::size_t m : kept)
        if (r.measured[m]) specimen.push_back(calibration.world_from_rig * r.points_m[m]);
      probe =
          probe_pose_from_shaft_markers(in.cameras, st.shaft_detections, calibration.world_from_rig,
                                        *shaft_distances, specimen, options.probe);
    }
    if (probe) {
      ++sum.probe_from_markers;
      if (st.truth_probe_tip_m) {
        const double e = (probe->tip_m - *st.truth_probe_tip_m).norm();
        p_ss += e * e;
        ++p_n;
        sum.probe_truth_max_error_m = std::max(sum.probe_truth_max_error_m, e);
        if (st.truth_probe_axis && st.truth_probe_axis->norm() > 0)
          sum.probe_axis_truth_max_error_rad = std::max(
              sum.probe_axis_truth_max_error_rad,
              std::acos(std::clamp(probe->axis.dot(st.truth_probe_axis->normalized()), -1.0, 1.0)));
      }
    } else if (st.probe_tip_m) {
      ++sum.probe_fallbacks;
      probe = ProbePose{};
      probe->tip_m = *st.probe_tip_m;  // a 4-DOF arm holds the probe vertical: axis +z
    } else {
      ++sum.probe_missing;
    }
    out.probe.push_back(probe);
    // In the template frame.
    std::optional<Eigen::Vector3d> tip_tpl;
    Eigen::Vector3d down = R_tpl_world * Eigen::Vector3d(0, 0, -1);
    if (probe) {
      tip_tpl = reg->T * probe->tip_m;
      down = -(R_tpl_world * probe->axis);
    }

    material::Example ex;
    ex.name = st.location >= 0 ? fmt::format("loc{}_lvl{}_step{}", st.location, st.level, st.step)
                               : fmt::format("trigger{}", st.trigger_index);
    ex.positions_m = mesh.nodes;
    ex.visible.assign(nodes.size(), 0);
    std::vector<Eigen::Vector3d> known_p, known_d;
    for (std::size_t i = 0; i < kept.size(); ++i) {
      const std::size_t m = kept[i];
      if (!r.measured[m]) continue;
      const auto n = static_cast<std::size_t>(out.marker_node[i]);
      const Eigen::Vector3d x = T_tpl_rig * r.points_m[m];
      ex.positions_m.row(static_cast<Eigen::Index>(n)) = x.transpose();
      ex.visible[n] = 1;
      known_p.push_back(nodes[n]);
      known_d.push_back(x - nodes[n]);
      ++measured_pairs;
    }
    std::vector<Eigen::Vector3d> query;
    std::vector<std::size_t> query_node;
    std::vector<std::uint8_t> query_on_surface;
    for (std::size_t n = 0; n < nodes.size(); ++n)
      if (!ex.visible[n]) {
        query.push_back(nodes[n]);
        query_node.push_back(n);
        query_on_surface.push_back(on_surface[n]);
      }
    // The RBF system is dense (cubic in its centres): keep the measured markers nearest to where
    // the fill matters — the unmeasured marker nodes and the probe — (options.max_fill_centres),
    // which decide the filled markers; far invisible nodes only get a plausible smooth guess.
    if (options.max_fill_centres > 0 && known_p.size() > options.max_fill_centres) {
      std::vector<Eigen::Vector3d> focus;
      for (std::size_t i = 0; i < kept.size(); ++i)
        if (!r.measured[kept[i]])
          focus.push_back(nodes[static_cast<std::size_t>(out.marker_node[i])]);
      if (tip_tpl) focus.push_back(*tip_tpl);
      if (!focus.empty()) {
        std::vector<std::pair<double, std::size_t>> order;
        for (std::size_t i = 0; i < known_p.size(); ++i) {
          double d = std::numeric_limits<double>::infinity();
          for (const auto& f : focus) d = std::min(d, (known_p[i] - f).squaredNorm());
          order.emplace_back(d, i);
        }
        std::nth_element(order.begin(),
                         order.begin() + static_cast<std::ptrdiff_t>(options.max_fill_centres),
                         order.end());
        std::vector<Eigen::Vector3d> p2, d2;
        for (std::size_t i = 0; i < options.max_fill_centres; ++i) {
          p2.push_back(known_p[order[i].second]);
          d2.push_back(known_d[order[i].second]);
        }
        known_p = std::move(p2);
        known_d = std::move(d2);
      }
    }
    std::vector<Eigen::Vector3d> filled =
        interpolate_displacements(known_p, known_d, query, options.fill_regularization_m);
    // The probe is a constraint too (see fill_with_probe_contact).
    if (tip_tpl && options.probe_constraint)
      filled = fill_with_probe_contact(known_p, known_d, query, query_on_surface, surface_nodes,
                                       *tip_tpl, down, options, std::move(filled));
    for (std::size_t q = 0; q < query.size(); ++q)
      ex.positions_m.row(static_cast<Eigen::Index>(query_node[q])) =
          (query[q] + filled[q]).transpose();
    // Fixed nodes stay at rest (the samples format ignores their positions anyway).
    for (int n : fixed) ex.positions_m.row(n) = mesh.nodes.row(n);
    ex.fixed_nodes = fixed;

    // Probe and forces.
    if (tip_tpl) {
      const Eigen::Vector3d tip = *tip_tpl;
      ex.probe.shape = "sphere";
      ex.probe.radius_m = *options.probe_radius_m;
      ex.probe.position_m = tip - *options.probe_radius_m * down;
      ex.probe.direction = down;
    }
    if (st.has_force) {
      const Eigen::Vector3d f = -(R_tpl_world * st.ft_force_n);  // on the specimen
      std::vector<std::pair<int, double>> w;
      double wsum = 0;
      if (tip_tpl) {
        const Eigen::Vector3d c = ex.probe.position_m;
        for (std::size_t n = 0; n < nodes.size(); ++n) {
          if (std::find(fixed.begin(), fixed.end(), static_cast<int>(n)) != fixed.end()) continue;
          const Eigen::Vector3d x = ex.positions_m.row(static_cast<Eigen::Index>(n)).transpose();
          const double depth =
              *options.probe_radius_m + options.contact_tolerance_m - (x - c).norm();
          if (depth > 0) {
            w.emplace_back(static_cast<int>(n), depth);
            wsum += depth;
          }
        }
        if (w.empty()) {
          double best = std::numeric_limits<double>::infinity();
          int bn = -1;
          const Eigen::Vector3d tip = *tip_tpl;
          for (std::size_t n = 0; n < nodes.size(); ++n) {
            const double d =
                (ex.positions_m.row(static_cast<Eigen::Index>(n)).transpose() - tip).norm();
            if (d < best && !std::binary_search(fixed.begin(), fixed.end(), static_cast<int>(n))) {
              best = d;
              bn = static_cast<int>(n);
            }
          }
          if (bn >= 0) {
            w.emplace_back(bn, 1.0);
            wsum = 1.0;
          }
        }
      }
      if (f.norm() > 0 && wsum > 0)
        for (const auto& [n, wi] : w) ex.forces.push_back({n, f * (wi / wsum)});
    }

    // Truth.
    if (in.has_truth && st.truth_markers_m.size() == in.steps[0].truth_markers_m.size()) {
      const Eigen::Isometry3d T_world_tpl = reg->T.inverse();
      for (std::size_t i = 0; i < kept.size(); ++i) {
        const std::size_t m = kept[i];
        if (truth_of[m] < 0) continue;
        const Eigen::Vector3d truth = st.truth_markers_m[static_cast<std::size_t>(truth_of[m])];
        const auto n = static_cast<Eigen::Index>(out.marker_node[i]);
        const Eigen::Vector3d x = T_world_tpl * Eigen::Vector3d(ex.positions_m.row(n).transpose());
        const double e = (x - truth).norm();
        if (r.measured[m]) {
          const double e_raw = (calibration.world_from_rig * r.points_m[m] - truth).norm();
          t_ss += e_raw * e_raw;
          t_max = std::max(t_max, e_raw);
          ++t_n;
        } else {
          f_ss += e * e;
          f_max = std::max(f_max, e);
          ++f_n;
        }
      }
      // Visibility per the truth: in >= 2 images (projected with the calibration) and not
      // occluded there.
      std::vector<int> tracked_of_truth(st.truth_markers_m.size(), -1);
      for (std::size_t m = 0; m < nm; ++m)
        if (truth_of[m] >= 0)
          tracked_of_truth[static_cast<std::size_t>(truth_of[m])] = static_cast<int>(m);
      const Eigen::Isometry3d rig_from_world = calibration.world_from_rig.inverse();
      for (std::size_t i = 0; i < st.truth_markers_m.size(); ++i) {
        int seen = 0;
        for (std::size_t c = 0; c < nc; ++c) {
          const auto p = in.cameras[c].project(rig_from_world * st.truth_markers_m[i]);
          if (!p || p->x() < 3 || p->y() < 3 || p->x() > in.cameras[c].width - 4 ||
              p->y() > in.cameras[c].height - 4)
            continue;
          if (c < st.truth_occluded.size() &&
              std::find(st.truth_occluded[c].begin(), st.truth_occluded[c].end(), i) !=
                  st.truth_occluded[c].end())
            continue;
          ++seen;
        }
        if (seen < 2) continue;
        ++t_visible;
        const int m = tracked_of_truth[i];
        if (m >= 0 && r.measured[static_cast<std::size_t>(m)]) ++t_measured;
      }
    }
    out.samples.examples.push_back(std::move(ex));
  }
  sum.times.registration_s = seconds_since(t0);
  sum.matched_fraction =
      static_cast<double>(measured_pairs) / static_cast<double>(kept.size() * in.steps.size());
  sum.detections_matched_fraction =
      all_dets ? static_cast<double>(matched_dets) / static_cast<double>(all_dets) : 0.0;
  double rs = 0, rn = 0;
  for (const StepResult& r : results) {
    double v = 0;
    for (std::size_t m = 0; m < nm; ++m) v += r.measured[m] ? r.views[m] : 0;
    rs += r.reprojection_rms_px * r.reprojection_rms_px * v;
    rn += v;
  }
  sum.reprojection_rms_px = rn > 0 ? std::sqrt(rs / rn) : 0.0;
  sum.has_truth = in.has_truth;
  if (in.has_truth) {
    sum.truth_rms_error_m = t_n ? std::sqrt(t_ss / static_cast<double>(t_n)) : 0.0;
    sum.truth_max_error_m = t_max;
    sum.truth_matched_fraction =
        t_visible ? static_cast<double>(t_measured) / static_cast<double>(t_visible) : 0.0;
    sum.filled = f_n;
    sum.filled_truth_rms_error_m = f_n ? std::sqrt(f_ss / static_cast<double>(f_n)) : 0.0;
    sum.filled_truth_max_error_m = f_max;
  } else {
    for (const StepResult& r : results)
      for (std::size_t m : kept) sum.filled += r.measured[m] ? 0 : 1;
  }
  sum.has_probe_truth = p_n > 0;
  sum.probe_truth_rms_error_m = p_n ? std::sqrt(p_ss / static_cast<double>(p_n)) : 0.0;
  if (!options.probe_from_shaft_markers)
    sum.probe_source = "arm pose (shaft markers not used)";
  else if (!shaft_distances)
    sum.probe_source = "arm pose (no shaft-marker geometry: give the marker distances)";
  else if (sum.probe_fallbacks == 0 && sum.probe_missing == 0)
    sum.probe_source = "shaft markers in every step";
  else
    sum.probe_source = fmt::format(
        "shaft markers in {} of {} steps; arm pose in {} (fewer than two shaft markers seen){}",
        sum.probe_from_markers, in.steps.size(), sum.probe_fallbacks,
        sum.probe_missing ? fmt::format("; no probe pose in {}", sum.probe_missing) : "");
  sum.times.total_s = in.times.total_s + sum.times.matching_s + sum.times.registration_s;
  HC_RETURN_IF_ERROR(material::validate_samples(out.samples));
  return out;
}

}  // namespace hc::tracking
