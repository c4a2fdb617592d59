// hardcopy track: a recorded session -> force-displacement samples (thesis Sec. 4.4.2, 5.6).
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "camera/camera_model.h"
#include "command.h"
#include "common/json.h"
#include "common/tet_mesh_io.h"
#include "processing/markers/dots.h"
#include "processing/material/samples.h"
#include "processing/tracking/session_tracking.h"

namespace hc::cli {
namespace {

struct TrackArgs {
  std::string session;
  std::string calib;
  std::string templ;
  std::string output;
  std::size_t max_steps = 0;
  std::optional<double> probe_radius_m;
  double match_distance_m = 1.0e-3;
  double max_registration_rms_m = tracking::SessionTrackOptions{}.max_registration_rms_m;
  std::string markers = "blobs";
  std::vector<double> shaft_markers_m;
  bool probe_from_arm = false;
  int threads = 0;
  bool json = false;
};

// `--markers blobs | color:L,a,b,TOL`: the dot detector. A colour is a box of half-width TOL
// around (L, a, b) in CIE Lab (L in [0, 100], a and b in [-128, 127]).
Result<std::optional<markers::ColorDotOptions>> parse_markers(const std::string& spec) {
  if (spec == "blobs") return std::optional<markers::ColorDotOptions>();
  const std::string bad = fmt::format(
      "--markers '{}': expected 'blobs' or 'color:L,a,b,TOL' (CIE Lab centre and half-width)",
      spec);
  if (!spec.starts_with("color:")) return invalid_argument(bad);
  std::vector<double> v;
  std::size_t pos = 6;
  while (pos <= spec.size()) {
    const std::size_t comma = std::min(spec.find(',', pos), spec.size());
    const std::string item = spec.substr(pos, comma - pos);
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(x))
      return invalid_argument(bad);
    v.push_back(x);
    pos = comma + 1;
  }
  if (v.size() != 4 || !(v[3] > 0)) return invalid_argument(bad);
  markers::ColorDotOptions o;
  markers::ColorClass c;
  c.name = "marker";
  c.lab_min = Eigen::Vector3d(v[0], v[1], v[2]) - Eigen::Vector3d::Constant(v[3]);
  c.lab_max = Eigen::Vector3d(v[0], v[1], v[2]) + Eigen::Vector3d::Constant(v[3]);
  o.colors.push_back(c);
  if (Status s = o.validate(); !s.ok()) return invalid_argument(bad + ": " + s.message());
  return std::optional<markers::ColorDotOptions>(o);
}

int run_track(const GlobalOptions& global, const TrackArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "track";
  const auto t0 = std::chrono::steady_clock::now();
  Result<RigCalibration> cal = read_rig_calibration(args.calib);
  if (!cal.ok()) return ctx.fail(kName, invalid_argument(cal.status().to_string()));
  Result<TetMesh> templ = read_tetgen(args.templ);
  if (!templ.ok())
    return ctx.fail(kName, invalid_argument(fmt::format("template {}: {}", args.templ,
                                                        templ.status().to_string())));
  Result<std::optional<markers::ColorDotOptions>> color = parse_markers(args.markers);
  if (!color.ok()) return ctx.fail(kName, color.status());
  if (!args.shaft_markers_m.empty() &&
      (args.shaft_markers_m.size() != 2 || !(args.shaft_markers_m[0] > 0) ||
       !(args.shaft_markers_m[1] > args.shaft_markers_m[0])))
    return ctx.fail(kName,
                    invalid_argument("--shaft-markers: expected D0,D1 with 0 < D0 < D1 (m)"));
  tracking::SessionReadOptions ro;
  ro.color = *color;
  ro.max_steps = args.max_steps;
  ro.threads = args.threads;
  ro.progress = ctx.progress();
  Result<tracking::SessionDetections> det =
      tracking::read_session_detections(args.session, *cal, ro);
  if (!det.ok()) return ctx.fail(kName, det.status());
  tracking::SessionTrackOptions to;
  to.probe_radius_m = args.probe_radius_m;
  to.template_match_distance_m = args.match_distance_m;
  to.max_registration_rms_m = args.max_registration_rms_m;
  to.probe_from_shaft_markers = !args.probe_from_arm;
  if (!args.shaft_markers_m.empty())
    to.probe.shaft_marker_distances_m = {args.shaft_markers_m[0], args.shaft_markers_m[1]};
  Result<tracking::TrackedSession> tr = tracking::track_detections(*det, *cal, *templ, to);
  if (!tr.ok()) return ctx.fail(kName, tr.status());
  if (Status s = material::save_samples(args.output, tr->samples); !s.ok())
    return ctx.fail(kName, s);
  const tracking::TrackSummary& s = tr->summary;
  const double time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (args.json) {
    Json j{{"session", args.session},
           {"output", args.output},
           {"markers", s.markers},
           {"steps", s.steps},
           {"template_nodes", templ->num_nodes()},
           {"matched_fraction", s.matched_fraction},
           {"detections_matched_fraction", s.detections_matched_fraction},
           {"reprojection_rms_px", s.reprojection_rms_px},
           {"registration_rms_m", s.registration_rms_m},
           {"filled", s.filled},
           {"probe_source", s.probe_source},
           {"probe_from_markers", s.probe_from_markers},
           {"probe_fallbacks", s.probe_fallbacks},
           {"time_s", time_s},
           {"stage_times_s",
            {{"decode", s.times.decode_s},
             {"detection_cpu", s.times.detection_s},
             {"frames_wall", s.times.frames_s},
             {"matching_triangulation", s.times.matching_s},
             {"registration_filling", s.times.registration_s}}}};
    if (s.has_truth) {
      j["truth_rms_error_m"] = s.truth_rms_error_m;
      j["truth_max_error_m"] = s.truth_max_error_m;
      j["truth_matched_fraction"] = s.truth_matched_fraction;
      j["filled_truth_rms_error_m"] = s.filled_truth_rms_error_m;
      j["filled_truth_max_error_m"] = s.filled_truth_max_error_m;
    }
    if (s.has_probe_truth) {
      j["probe_truth_rms_error_m"] = s.probe_truth_rms_error_m;
      j["probe_truth_max_error_m"] = s.probe_truth_max_error_m;
      j["probe_axis_truth_max_error_rad"] = s.probe_axis_truth_max_error_rad;
    }
    fmt::print("{}\n", j.dump(2));
  } else {
    fmt::print(
        "{} markers tracked through {} steps ({:.1f} % measured), reprojection RMS {:.3f} px",
        s.markers, s.steps, 100.0 * s.matched_fraction, s.reprojection_rms_px);
    if (s.has_truth)
      fmt::print(", truth error RMS {:.4f} mm (max {:.4f} mm)", s.truth_rms_error_m * 1e3,
                 s.truth_max_error_m * 1e3);
    fmt::print("; probe pose: {}", s.probe_source);
    if (s.has_probe_truth)
      fmt::print(" (tip error RMS {:.4f} mm)", s.probe_truth_rms_error_m * 1e3);
    fmt::print("; {:.1f} s -> {}\n", time_s, args.output);
  }
  return kExitYes;
}

void add_track_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto args = std::make_shared<TrackArgs>();
  CLI::App* t = app.add_subcommand(
      "track",
      "Track the markers of a recorded session and write force-displacement samples: dots in "
      "every step frame, epipolar matching, triangulation, tracking through the steps, "
      "registration to the template (TetGen .node/.ele in the calibration's world frame), "
      "filling of occluded markers, forces from the F/T channel");
  t->add_option("SESSION", args->session, "Session MCAP file")->required();
  t->add_option("--calib", args->calib, "Rig calibration YAML (hardcopy calib cameras)")
      ->required();
  t->add_option("--template", args->templ,
                "Template tet mesh: TetGen BASE, BASE.node or BASE.ele; surface nodes at the "
                "markers, world frame, metres")
      ->required();
  t->add_option("-o,--output", args->output, "Samples JSON to write (hardcopy.samples)")
      ->required();
  t->add_option("--max-steps", args->max_steps, "Track only the first N steps (0: all)")
      ->capture_default_str();
  t->add_option("--probe-radius", args->probe_radius_m,
                "Probe tip sphere radius, m (default: the session's rig config, else 0.005)")
      ->check(kPositive);
  t->add_option("--match-distance", args->match_distance_m,
                "Largest marker-to-template-node distance after registration, m")
      ->capture_default_str()
      ->check(kPositive);
  t->add_option("--max-registration-rms", args->max_registration_rms_m,
                "Largest RMS distance of the first step's markers from their template nodes, m "
                "(the offset enters every displacement)")
      ->capture_default_str()
      ->check(kPositive);
  t->add_option("--markers", args->markers,
                "Dot detector: 'blobs' (bright dots on a dark surface, Otsu threshold) or "
                "'color:L,a,b,TOL' (painted dots of one colour: CIE Lab box of half-width TOL "
                "around L in [0, 100], a, b in [-128, 127]; rgb8 frames; thesis 4.4.2)")
      ->capture_default_str();
  t->add_option("--shaft-markers", args->shaft_markers_m,
                "The probe's two shaft markers' distances from the tip along the shaft, m "
                "(D0,D1; default: the session's rig config); the probe pose per step comes from "
                "them, else from the arm")
      ->delimiter(',')
      ->expected(2);
  t->add_flag("--probe-from-arm", args->probe_from_arm,
              "Take the probe pose from the arm's reported pose, not the shaft markers");
  t->add_option("--threads", args->threads, "Detection threads (0: all cores)")
      ->capture_default_str();
  t->add_flag("--json", args->json, "Print one JSON object");
  t->callback([&global, args, exit_code] { *exit_code = run_track(global, *args); });
}

}  // namespace

HC_REGISTER_COMMANDS_ORDERED(45, add_track_commands);

}  // namespace hc::cli
