#include "processing/tracking/session_tracking.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

#include "session_tracking_internal.h"

namespace hc::tracking {
namespace {

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

}  // namespace

std::optional<ProbePose> probe_pose_from_shaft_markers(
    const std::vector<CameraModel>& cameras, const FrameDetections& shaft_detections,
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

namespace {

// Tracks every step (the first initialises the tracker). Markers found in later steps are
// unmeasured in the steps before.
Result<std::vector<StepResult>> track_steps(const SessionDetections& in, MarkerTracker* tracker) {
  std::vector<StepResult> results;
  results.reserve(in.steps.size());
  for (std::size_t k = 0; k < in.steps.size(); ++k) {
    Result<StepResult> r = k == 0 ? tracker->initialise(in.steps[k].detections)
                                  : tracker->track(in.steps[k].detections);
    if (!r.ok()) return r.status().with_context(fmt::format("step {}", k));
    results.push_back(std::move(*r));
  }
  for (StepResult& r : results) {
    r.points_m.resize(tracker->num_markers(), Eigen::Vector3d::Zero());
    r.measured.resize(tracker->num_markers(), 0);
    r.views.resize(tracker->num_markers(), 0);
  }
  return results;
}

// The first step's markers (world frame) registered to the template's nodes; refused with the
// cause when they sit off the nodes, since that offset would be in every displacement.
Result<IcpResult> register_to_template(const std::vector<Eigen::Vector3d>& first_world,
                                       const std::vector<Eigen::Vector3d>& nodes,
                                       const SessionTrackOptions& options) {
  Result<IcpResult> reg =
      icp(first_world, nodes, Eigen::Isometry3d::Identity(), options.template_match_distance_m);
  if (!reg.ok())
    return failed_precondition(
        fmt::format("registration of the markers to the template failed: {} (is the template in "
                    "the world frame of the calibration?)",
                    reg.status().message()));
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
  return reg;
}

// The template node of each tracked marker (-1: none). The first step's markers take their
// registration match. Markers farther than the match distance from their node (deformed in their
// first step, or found in a later step) are assigned by their estimated rest position: their
// position minus the displacement interpolated from the markers already assigned and measured in
// that step, nearest free node first.
std::vector<int> assign_marker_nodes(const std::vector<StepResult>& results,
                                     const std::vector<int>& birth, const IcpResult& reg,
                                     const Eigen::Isometry3d& T_tpl_rig,
                                     const std::vector<Eigen::Vector3d>& nodes,
                                     double match_distance_m) {
  std::vector<int> node_of(birth.size(), -1);
  std::vector<int> marker_of_node(nodes.size(), -1);
  for (std::size_t m = 0; m < results[0].points_m.size(); ++m)
    if (reg.match[m] >= 0) {
      node_of[m] = reg.match[m];
      marker_of_node[static_cast<std::size_t>(reg.match[m])] = static_cast<int>(m);
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
          if (dist <= match_distance_m) cand.emplace_back(dist, qm[i], n);
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
  return node_of;
}

// What the steps share: the registration, the template's nodes and the kept markers.
struct TrackContext {
  const SessionDetections& in;
  const RigCalibration& calibration;
  const TetMesh& mesh;
  const SessionTrackOptions& options;
  const std::vector<StepResult>& results;
  Eigen::Isometry3d T_tpl_world = Eigen::Isometry3d::Identity();  // registration: world -> template
  Eigen::Isometry3d T_tpl_rig = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> nodes{};          // template rest positions
  std::vector<std::uint8_t> on_surface{};        // per node
  std::vector<Eigen::Vector3d> surface_nodes{};  // rest positions, for the probe's indentation
  std::vector<int> fixed{};                      // the template's bottom, ascending
  std::vector<std::size_t> kept{};               // tracked marker ids registered to a node
  std::vector<int> marker_node{};                // per kept marker
  std::vector<int> truth_of{};                   // per tracked marker: truth index, -1 none
  std::optional<std::array<double, 2>> shaft_distances{};
};

// Sums for the summary's truth and probe figures.
struct TruthStats {
  double t_ss = 0, t_max = 0, f_ss = 0, f_max = 0, p_ss = 0;
  std::size_t t_n = 0, f_n = 0, t_visible = 0, t_measured = 0, p_n = 0;
};

// Tracked marker -> truth marker index, by the marker's position in its birth step (within 1 mm).
std::vector<int> truth_indices(const TrackContext& c, const std::vector<int>& birth) {
  std::vector<int> truth_of(birth.size(), -1);
  if (!c.in.has_truth) return truth_of;
  for (std::size_t m = 0; m < birth.size(); ++m) {
    const auto b = static_cast<std::size_t>(birth[m]);
    const auto& tm = c.in.steps[b].truth_markers_m;
    const Eigen::Vector3d xw = c.calibration.world_from_rig * c.results[b].points_m[m];
    double best = 1e-3;
    for (std::size_t i = 0; i < tm.size(); ++i) {
      const double d = (tm[i] - xw).norm();
      if (d < best) {
        best = d;
        truth_of[m] = static_cast<int>(i);
      }
    }
  }
  return truth_of;
}

// The probe's pose in step k: from the shaft markers, else the arm's reported pose (world frame).
std::optional<ProbePose> step_probe_pose(const TrackContext& c, std::size_t k, TrackSummary* sum,
                                         TruthStats* ts) {
  const SessionStep& st = c.in.steps[k];
  const StepResult& r = c.results[k];
  std::optional<ProbePose> probe;
  if (c.options.probe_from_shaft_markers && c.shaft_distances) {
    std::vector<Eigen::Vector3d> specimen;
    for (std::size_t m : c.kept)
      if (r.measured[m]) specimen.push_back(c.calibration.world_from_rig * r.points_m[m]);
    probe = probe_pose_from_shaft_markers(c.in.cameras, st.shaft_detections,
                                          c.calibration.world_from_rig, *c.shaft_distances,
                                          specimen, c.options.probe);
  }
  if (probe) {
    ++sum->probe_from_markers;
    if (st.truth_probe_tip_m) {
      const double e = (probe->tip_m - *st.truth_probe_tip_m).norm();
      ts->p_ss += e * e;
      ++ts->p_n;
      sum->probe_truth_max_error_m = std::max(sum->probe_truth_max_error_m, e);
      if (st.truth_probe_axis && st.truth_probe_axis->norm() > 0)
        sum->probe_axis_truth_max_error_rad = std::max(
            sum->probe_axis_truth_max_error_rad,
            std::acos(std::clamp(probe->axis.dot(st.truth_probe_axis->normalized()), -1.0, 1.0)));
    }
  } else if (st.probe_tip_m) {
    ++sum->probe_fallbacks;
    probe = ProbePose{};
    probe->tip_m = *st.probe_tip_m;  // a 4-DOF arm holds the probe vertical: axis +z
  } else {
    ++sum->probe_missing;
  }
  return probe;
}

// The RBF system is dense (cubic in its centres): keeps the `max` measured markers nearest to
// where the fill matters — the unmeasured marker nodes and the probe — which decide the filled
// markers; far invisible nodes only get a plausible smooth guess.
void keep_centres_near_focus(const std::vector<Eigen::Vector3d>& focus, std::size_t max,
                             std::vector<Eigen::Vector3d>* known_p,
                             std::vector<Eigen::Vector3d>* known_d) {
  if (focus.empty()) return;
  std::vector<std::pair<double, std::size_t>> order;
  for (std::size_t i = 0; i < known_p->size(); ++i) {
    double d = std::numeric_limits<double>::infinity();
    for (const auto& f : focus) d = std::min(d, ((*known_p)[i] - f).squaredNorm());
    order.emplace_back(d, i);
  }
  std::nth_element(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(max), order.end());
  std::vector<Eigen::Vector3d> p2, d2;
  for (std::size_t i = 0; i < max; ++i) {
    p2.push_back((*known_p)[order[i].second]);
    d2.push_back((*known_d)[order[i].second]);
  }
  *known_p = std::move(p2);
  *known_d = std::move(d2);
}

// Node positions of step k: measured markers where seen, the occlusion fill elsewhere, fixed
// nodes at rest. Returns the number of measured (marker, node) pairs.
std::size_t fill_step_positions(const TrackContext& c, std::size_t k,
                                const std::optional<Eigen::Vector3d>& tip_tpl,
                                const Eigen::Vector3d& down, material::Example* ex) {
  const StepResult& r = c.results[k];
  const SessionTrackOptions& options = c.options;
  ex->positions_m = c.mesh.nodes;
  ex->visible.assign(c.nodes.size(), 0);
  std::size_t measured = 0;
  std::vector<Eigen::Vector3d> known_p, known_d;
  for (std::size_t i = 0; i < c.kept.size(); ++i) {
    const std::size_t m = c.kept[i];
    if (!r.measured[m]) continue;
    const auto n = static_cast<std::size_t>(c.marker_node[i]);
    const Eigen::Vector3d x = c.T_tpl_rig * r.points_m[m];
    ex->positions_m.row(static_cast<Eigen::Index>(n)) = x.transpose();
    ex->visible[n] = 1;
    known_p.push_back(c.nodes[n]);
    known_d.push_back(x - c.nodes[n]);
    ++measured;
  }
  std::vector<Eigen::Vector3d> query;
  std::vector<std::size_t> query_node;
  std::vector<std::uint8_t> query_on_surface;
  for (std::size_t n = 0; n < c.nodes.size(); ++n)
    if (!ex->visible[n]) {
      query.push_back(c.nodes[n]);
      query_node.push_back(n);
      query_on_surface.push_back(c.on_surface[n]);
    }
  if (options.max_fill_centres > 0 && known_p.size() > options.max_fill_centres) {
    std::vector<Eigen::Vector3d> focus;
    for (std::size_t i = 0; i < c.kept.size(); ++i)
      if (!r.measured[c.kept[i]])
        focus.push_back(c.nodes[static_cast<std::size_t>(c.marker_node[i])]);
    if (tip_tpl) focus.push_back(*tip_tpl);
    keep_centres_near_focus(focus, options.max_fill_centres, &known_p, &known_d);
  }
  std::vector<Eigen::Vector3d> filled =
      interpolate_displacements(known_p, known_d, query, options.fill_regularization_m);
  // The probe is a constraint too (see fill_with_probe_contact).
  if (tip_tpl && options.probe_constraint)
    filled = fill_with_probe_contact(known_p, known_d, query, query_on_surface, c.surface_nodes,
                                     *tip_tpl, down, options, std::move(filled));
  for (std::size_t q = 0; q < query.size(); ++q)
    ex->positions_m.row(static_cast<Eigen::Index>(query_node[q])) =
        (query[q] + filled[q]).transpose();
  // Fixed nodes stay at rest (the samples format ignores their positions anyway).
  for (int n : c.fixed) ex->positions_m.row(n) = c.mesh.nodes.row(n);
  ex->fixed_nodes = c.fixed;
  return measured;
}

// The force-torque sensor's force, on the specimen, spread over the free nodes inside the probe
// sphere (weighted by depth), else put on the free node nearest the tip.
void distribute_probe_force(const TrackContext& c, const SessionStep& st,
                            const std::optional<Eigen::Vector3d>& tip_tpl, material::Example* ex) {
  const SessionTrackOptions& options = c.options;
  const Eigen::Vector3d f = -(c.T_tpl_world.linear() * st.ft_force_n);  // on the specimen
  std::vector<std::pair<int, double>> w;
  double wsum = 0;
  if (tip_tpl) {
    const Eigen::Vector3d centre = ex->probe.position_m;
    for (std::size_t n = 0; n < c.nodes.size(); ++n) {
      if (std::find(c.fixed.begin(), c.fixed.end(), static_cast<int>(n)) != c.fixed.end()) continue;
      const Eigen::Vector3d x = ex->positions_m.row(static_cast<Eigen::Index>(n)).transpose();
      const double depth =
          *options.probe_radius_m + options.contact_tolerance_m - (x - centre).norm();
      if (depth > 0) {
        w.emplace_back(static_cast<int>(n), depth);
        wsum += depth;
      }
    }
    if (w.empty()) {
      double best = std::numeric_limits<double>::infinity();
      int bn = -1;
      const Eigen::Vector3d tip = *tip_tpl;
      for (std::size_t n = 0; n < c.nodes.size(); ++n) {
        const double d =
            (ex->positions_m.row(static_cast<Eigen::Index>(n)).transpose() - tip).norm();
        if (d < best && !std::binary_search(c.fixed.begin(), c.fixed.end(), static_cast<int>(n))) {
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
    for (const auto& [n, wi] : w) ex->forces.push_back({n, f * (wi / wsum)});
}

// Errors of step k's measured and filled markers against the truth, and visibility per the truth:
// in >= 2 images (projected with the calibration) and not occluded there.
void accumulate_truth(const TrackContext& c, std::size_t k, const material::Example& ex,
                      TruthStats* ts) {
  const SessionStep& st = c.in.steps[k];
  const StepResult& r = c.results[k];
  if (!c.in.has_truth || st.truth_markers_m.size() != c.in.steps[0].truth_markers_m.size()) return;
  const Eigen::Isometry3d T_world_tpl = c.T_tpl_world.inverse();
  for (std::size_t i = 0; i < c.kept.size(); ++i) {
    const std::size_t m = c.kept[i];
    if (c.truth_of[m] < 0) continue;
    const Eigen::Vector3d truth = st.truth_markers_m[static_cast<std::size_t>(c.truth_of[m])];
    const auto n = static_cast<Eigen::Index>(c.marker_node[i]);
    const Eigen::Vector3d x = T_world_tpl * Eigen::Vector3d(ex.positions_m.row(n).transpose());
    const double e = (x - truth).norm();
    if (r.measured[m]) {
      const double e_raw = (c.calibration.world_from_rig * r.points_m[m] - truth).norm();
      ts->t_ss += e_raw * e_raw;
      ts->t_max = std::max(ts->t_max, e_raw);
      ++ts->t_n;
    } else {
      ts->f_ss += e * e;
      ts->f_max = std::max(ts->f_max, e);
      ++ts->f_n;
    }
  }
  std::vector<int> tracked_of_truth(st.truth_markers_m.size(), -1);
  for (std::size_t m = 0; m < c.truth_of.size(); ++m)
    if (c.truth_of[m] >= 0)
      tracked_of_truth[static_cast<std::size_t>(c.truth_of[m])] = static_cast<int>(m);
  const Eigen::Isometry3d rig_from_world = c.calibration.world_from_rig.inverse();
  for (std::size_t i = 0; i < st.truth_markers_m.size(); ++i) {
    int seen = 0;
    for (std::size_t cam = 0; cam < c.in.cameras.size(); ++cam) {
      const CameraModel& model = c.in.cameras[cam];
      const auto p = model.project(rig_from_world * st.truth_markers_m[i]);
      if (!p || p->x() < 3 || p->y() < 3 || p->x() > model.width - 4 || p->y() > model.height - 4)
        continue;
      if (cam < st.truth_occluded.size() &&
          std::find(st.truth_occluded[cam].begin(), st.truth_occluded[cam].end(), i) !=
              st.truth_occluded[cam].end())
        continue;
      ++seen;
    }
    if (seen < 2) continue;
    ++ts->t_visible;
    const int m = tracked_of_truth[i];
    if (m >= 0 && r.measured[static_cast<std::size_t>(m)]) ++ts->t_measured;
  }
}

// The example of step k: node positions, probe, forces; truth figures into *ts.
material::Example step_example(const TrackContext& c, std::size_t k,
                               const std::optional<ProbePose>& probe, std::size_t* measured_pairs,
                               TruthStats* ts) {
  const SessionStep& st = c.in.steps[k];
  // In the template frame.
  std::optional<Eigen::Vector3d> tip_tpl;
  Eigen::Vector3d down = c.T_tpl_world.linear() * Eigen::Vector3d(0, 0, -1);
  if (probe) {
    tip_tpl = c.T_tpl_world * probe->tip_m;
    down = -(c.T_tpl_world.linear() * probe->axis);
  }
  material::Example ex;
  ex.name = st.location >= 0 ? fmt::format("loc{}_lvl{}_step{}", st.location, st.level, st.step)
                             : fmt::format("trigger{}", st.trigger_index);
  *measured_pairs += fill_step_positions(c, k, tip_tpl, down, &ex);
  if (tip_tpl) {
    ex.probe.shape = "sphere";
    ex.probe.radius_m = *c.options.probe_radius_m;
    ex.probe.position_m = *tip_tpl - *c.options.probe_radius_m * down;
    ex.probe.direction = down;
  }
  if (st.has_force) distribute_probe_force(c, st, tip_tpl, &ex);
  accumulate_truth(c, k, ex, ts);
  return ex;
}

// The summary's fractions, reprojection, truth and probe-source lines.
void finish_summary(const TrackContext& c, const TruthStats& ts, std::size_t measured_pairs,
                    std::size_t matched_dets, std::size_t all_dets, TrackSummary* sum) {
  const SessionDetections& in = c.in;
  sum->matched_fraction =
      static_cast<double>(measured_pairs) / static_cast<double>(c.kept.size() * in.steps.size());
  sum->detections_matched_fraction =
      all_dets ? static_cast<double>(matched_dets) / static_cast<double>(all_dets) : 0.0;
  double rs = 0, rn = 0;
  for (const StepResult& r : c.results) {
    double v = 0;
    for (std::size_t m = 0; m < r.measured.size(); ++m) v += r.measured[m] ? r.views[m] : 0;
    rs += r.reprojection_rms_px * r.reprojection_rms_px * v;
    rn += v;
  }
  sum->reprojection_rms_px = rn > 0 ? std::sqrt(rs / rn) : 0.0;
  sum->has_truth = in.has_truth;
  if (in.has_truth) {
    sum->truth_rms_error_m = ts.t_n ? std::sqrt(ts.t_ss / static_cast<double>(ts.t_n)) : 0.0;
    sum->truth_max_error_m = ts.t_max;
    sum->truth_matched_fraction =
        ts.t_visible ? static_cast<double>(ts.t_measured) / static_cast<double>(ts.t_visible) : 0.0;
    sum->filled = ts.f_n;
    sum->filled_truth_rms_error_m = ts.f_n ? std::sqrt(ts.f_ss / static_cast<double>(ts.f_n)) : 0.0;
    sum->filled_truth_max_error_m = ts.f_max;
  } else {
    for (const StepResult& r : c.results)
      for (std::size_t m : c.kept) sum->filled += r.measured[m] ? 0 : 1;
  }
  sum->has_probe_truth = ts.p_n > 0;
  sum->probe_truth_rms_error_m = ts.p_n ? std::sqrt(ts.p_ss / static_cast<double>(ts.p_n)) : 0.0;
  if (!c.options.probe_from_shaft_markers)
    sum->probe_source = "arm pose (shaft markers not used)";
  else if (!c.shaft_distances)
    sum->probe_source = "arm pose (no shaft-marker geometry: give the marker distances)";
  else if (sum->probe_fallbacks == 0 && sum->probe_missing == 0)
    sum->probe_source = "shaft markers in every step";
  else
    sum->probe_source = fmt::format(
        "shaft markers in {} of {} steps; arm pose in {} (fewer than two shaft markers seen){}",
        sum->probe_from_markers, in.steps.size(), sum->probe_fallbacks,
        sum->probe_missing ? fmt::format("; no probe pose in {}", sum->probe_missing) : "");
}

}  // namespace

Result<TrackedSession> track_detections(const SessionDetections& in,
                                        const RigCalibration& calibration,
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

  // ---- Tracking ----
  auto t0 = Clock::now();
  MarkerTracker tracker(in.cameras, options.track);
  HC_ASSIGN_OR_RETURN(const std::vector<StepResult> results, track_steps(in, &tracker));
  sum.times.matching_s = seconds_since(t0);
  if (tracker.num_markers() < 4)
    return failed_precondition(
        fmt::format("only {} markers found in the first step (need >= 4 in >= {} cameras)",
                    tracker.num_markers(), options.track.match.min_views));

  // ---- Registration to the template ----
  t0 = Clock::now();
  TrackContext c{in, calibration, mesh, options, results};
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    c.nodes.push_back(mesh.nodes.row(i).transpose());
  std::vector<Eigen::Vector3d> first_world;
  for (const Eigen::Vector3d& p : results[0].points_m)
    first_world.push_back(calibration.world_from_rig * p);
  HC_ASSIGN_OR_RETURN(const IcpResult reg, register_to_template(first_world, c.nodes, options));
  sum.registration_rms_m = reg.rms_m;
  c.T_tpl_world = reg.T;
  c.T_tpl_rig = reg.T * calibration.world_from_rig;
  const std::vector<int>& birth = tracker.birth_step();
  const std::vector<int> node_of = assign_marker_nodes(results, birth, reg, c.T_tpl_rig, c.nodes,
                                                       options.template_match_distance_m);
  for (std::size_t m = 0; m < node_of.size(); ++m)
    if (node_of[m] >= 0) {
      c.kept.push_back(m);
      c.marker_node.push_back(node_of[m]);
    }
  sum.markers = c.kept.size();
  sum.steps = in.steps.size();
  if (c.kept.size() < 4)
    return failed_precondition(fmt::format("only {} markers lie within {} m of a template node",
                                           c.kept.size(), options.template_match_distance_m));
  // Fixed nodes: the template's bottom.
  const double zmin = mesh.nodes.col(2).minCoeff();
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    if (mesh.nodes(i, 2) <= zmin + options.fixed_tolerance_m)
      c.fixed.push_back(static_cast<int>(i));
  c.on_surface = boundary_nodes(mesh);
  for (std::size_t n = 0; n < c.nodes.size(); ++n)
    if (c.on_surface[n]) c.surface_nodes.push_back(c.nodes[n]);
  c.truth_of = truth_indices(c, birth);
  c.shaft_distances = options.probe.shaft_marker_distances_m
                          ? options.probe.shaft_marker_distances_m
                          : in.shaft_marker_distances_m;

  out.samples.mesh = mesh;
  TruthStats ts;
  std::size_t measured_pairs = 0, matched_dets = 0, all_dets = 0;
  for (std::size_t k = 0; k < in.steps.size(); ++k) {
    all_dets += results[k].detections;
    matched_dets += results[k].matched_detections;
    const std::optional<ProbePose> probe = step_probe_pose(c, k, &sum, &ts);
    out.probe.push_back(probe);
    out.samples.examples.push_back(step_example(c, k, probe, &measured_pairs, &ts));
  }
  out.marker_node = c.marker_node;
  sum.times.registration_s = seconds_since(t0);
  finish_summary(c, ts, measured_pairs, matched_dets, all_dets, &sum);
  sum.times.total_s = in.times.total_s + sum.times.matching_s + sum.times.registration_s;
  HC_RETURN_IF_ERROR(material::validate_samples(out.samples));
  return out;
}

}  // namespace hc::tracking
