// hardcopy track: a recorded session -> force-displacement samples (thesis Sec. 4.4.2, 5.6).
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "calibration/cameras/camera_model.h"
#include "command.h"
#include "common/json.h"
#include "common/tet_mesh_io.h"
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
  double probe_radius_m = 0.005;
  double match_distance_m = 1.0e-3;
  int threads = 0;
  bool json = false;
};

int run_track(const GlobalOptions& global, const TrackArgs& args) {
  Context ctx(global);
  constexpr std::string_view kName = "track";
  const auto t0 = std::chrono::steady_clock::now();
  Result<calib::RigCalibration> cal = calib::read_rig_calibration(args.calib);
  if (!cal.ok()) return ctx.fail(kName, invalid_argument(cal.status().to_string()));
  Result<TetMesh> templ = read_tetgen(args.templ);
  if (!templ.ok())
    return ctx.fail(kName, invalid_argument(fmt::format("template {}: {}", args.templ,
                                                        templ.status().to_string())));
  tracking::SessionReadOptions ro;
  ro.max_steps = args.max_steps;
  ro.threads = args.threads;
  ro.progress = ctx.progress();
  Result<tracking::SessionDetections> det =
      tracking::read_session_detections(args.session, *cal, ro);
  if (!det.ok()) return ctx.fail(kName, det.status());
  tracking::SessionTrackOptions to;
  to.probe_radius_m = args.probe_radius_m;
  to.template_match_distance_m = args.match_distance_m;
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
    fmt::print("{}\n", j.dump(2));
  } else {
    fmt::print(
        "{} markers tracked through {} steps ({:.1f} % measured), reprojection RMS {:.3f} px",
        s.markers, s.steps, 100.0 * s.matched_fraction, s.reprojection_rms_px);
    if (s.has_truth)
      fmt::print(", truth error RMS {:.4f} mm (max {:.4f} mm)", s.truth_rms_error_m * 1e3,
                 s.truth_max_error_m * 1e3);
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
  t->add_option("--probe-radius", args->probe_radius_m, "Probe sphere radius, m")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  t->add_option("--match-distance", args->match_distance_m,
                "Largest marker-to-template-node distance after registration, m")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  t->add_option("--threads", args->threads, "Detection threads (0: all cores)")
      ->capture_default_str();
  t->add_flag("--json", args->json, "Print one JSON object");
  t->callback([&global, args, exit_code] { *exit_code = run_track(global, *args); });
}

}  // namespace

HC_REGISTER_COMMANDS_ORDERED(45, add_track_commands);

}  // namespace hc::cli
