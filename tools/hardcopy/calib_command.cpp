// hardcopy calib cameras: camera calibration from chessboard / ChArUco views (image files per
// camera or a recorded session), a joint bundle adjustment over all cameras, written as the rig
// calibration file (OpenCV FileStorage YAML). The `calib` group is created here (order 40);
// calib_aux_command.cpp (order 41) attaches hand-eye / ft-bias / fsr to it.
#include <fmt/format.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "calibration/cameras/board.h"
#include "calibration/cameras/board_sources.h"
#include "calibration/cameras/calibrate.h"
#include "camera/camera_model.h"
#include "command.h"
#include "common/json.h"

namespace hc::cli {
namespace {

struct CamerasArgs {
  std::string pattern;
  std::vector<std::string> images;
  std::string session;
  std::string output;
  bool fix_aspect_ratio = false;
  bool fix_k3 = false;
  bool zero_tangent = false;
  std::string loss = "none";
  double loss_scale_px = 1.0;
  double outlier_factor = 3.0;
  bool json = false;
};

Json camera_json(const CameraModel& m, const calib::CameraReport& r) {
  Json j = camera_to_json(m);
  j["rms_px"] = r.rms_px;
  j["views"] = r.views;
  j["points"] = r.points;
  j["initial_rms_px"] = r.initial_rms_px;
  if (!r.intrinsics_std.empty()) {
    static const char* kNames[] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"};
    Json s = Json::object();
    for (std::size_t i = 0; i < r.intrinsics_std.size() && i < 9; ++i)
      s[kNames[i]] = r.intrinsics_std[i];
    j["std"] = s;
  }
  if (!r.center_std_m.empty()) j["center_std_m"] = r.center_std_m;
  if (!r.parent.empty()) {
    j["chained_from"] = r.parent;
    j["shared_views_with_parent"] = r.shared_views_with_parent;
  }
  return j;
}

int run_cameras(const GlobalOptions& global, const CamerasArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  Context ctx(global);
  const char* cmd = "calib cameras";
  if (a.images.empty() == a.session.empty())
    return ctx.fail(cmd, invalid_argument("give either --images CAMERA=GLOB (once per camera) or "
                                          "--session S.mcap"));
  Result<calib::BoardSpec> board = calib::parse_board_spec(a.pattern);
  if (!board.ok()) return ctx.fail(cmd, board.status());
  calib::CalibrationOptions options;
  options.fix_aspect_ratio = a.fix_aspect_ratio;
  options.fix_k3 = a.fix_k3;
  options.zero_tangential = a.zero_tangent;
  options.outlier_factor = a.outlier_factor;
  options.loss_scale_px = a.loss_scale_px;
  options.progress = ctx.progress();
  if (a.loss == "huber")
    options.loss = calib::RobustLoss::kHuber;
  else if (a.loss == "cauchy")
    options.loss = calib::RobustLoss::kCauchy;
  else if (a.loss != "none")
    return ctx.fail(cmd, invalid_argument("--loss must be none, huber or cauchy"));
  if (!(a.loss_scale_px > 0.0) || !(a.outlier_factor > 1.0))
    return ctx.fail(cmd, invalid_argument("--loss-scale must be > 0 and --outlier-factor > 1"));

  calib::DetectionStats stats;
  Result<std::vector<calib::CameraObservations>> obs =
      [&]() -> Result<std::vector<calib::CameraObservations>> {
    if (!a.session.empty())
      return calib::detect_in_session(a.session, *board, {}, ctx.progress(), &stats);
    std::vector<calib::ImageSet> sets;
    for (const std::string& spec : a.images) {
      HC_ASSIGN_OR_RETURN(calib::ImageSet s, calib::expand_image_set(spec));
      sets.push_back(std::move(s));
    }
    return calib::detect_in_images(sets, *board, {}, ctx.progress(), &stats);
  }();
  if (!obs.ok()) return ctx.fail(cmd, obs.status());
  Result<calib::CalibrationSummary> s = calib::calibrate_rig(*obs, *board, options);
  if (!s.ok()) return ctx.fail(cmd, s.status());
  if (Status w = write_rig_calibration(a.output, s->rig); !w.ok()) return ctx.fail(cmd, w);
  const double time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool rig = s->rig.cameras.size() > 1;
  if (a.json) {
    Json cams = Json::object();
    for (std::size_t i = 0; i < s->rig.cameras.size(); ++i)
      cams[s->rig.cameras[i].name] = camera_json(s->rig.cameras[i], s->cameras[i]);
    Json views = Json::array(), outliers = Json::array();
    for (const calib::ViewReport& v : s->views) {
      Json j{{"camera", v.camera},
             {"view", v.view},
             {"points", v.points},
             {"rms_px", v.rms_px},
             {"outlier", v.outlier}};
      if (v.outlier) outliers.push_back(j);
      views.push_back(std::move(j));
    }
    Json out{{"output", a.output},
             {"pattern", board->to_string()},
             {"cameras", cams},
             {"camera_order",
              [&] {
                Json n = Json::array();
                for (const auto& c : s->rig.cameras) n.push_back(c.name);
                return n;
              }()},
             {"views", views},
             {"outlier_views", outliers},
             {"board_poses", s->board_poses},
             {"observations", s->observations},
             {"iterations", s->iterations},
             {"converged", s->converged},
             {"termination", s->termination},
             {"images", stats.images},
             {"boards_found", stats.boards_found},
             {"detect_time_s", stats.detect_time_s},
             {"solve_time_s", s->init_time_s + s->solve_time_s + s->covariance_time_s},
             {"time_s", time_s}};
    if (rig) out["joint_rms_px"] = s->joint_rms_px;
    if (!s->covariance_note.empty()) out["note"] = s->covariance_note;
    (void)print_json(out);
  } else {
    fmt::print("wrote {}: {} camera(s), {} board pose(s), {} corner observations\n", a.output,
               s->rig.cameras.size(), s->board_poses, s->observations);
    for (std::size_t i = 0; i < s->rig.cameras.size(); ++i) {
      const CameraModel& m = s->rig.cameras[i];
      fmt::print("  {}: rms {:.4f} px, fx {:.3f} fy {:.3f} cx {:.3f} cy {:.3f}, |t| {:.2f} mm\n",
                 m.name, s->cameras[i].rms_px, m.fx, m.fy, m.cx, m.cy, 1e3 * m.t_m.norm());
    }
    if (rig) fmt::print("  joint rms {:.4f} px\n", s->joint_rms_px);
    if (!s->converged) fmt::print("  not converged: {}\n", s->termination);
    for (const calib::ViewReport& v : s->outliers())
      fmt::print("  outlier view: camera {} view {} rms {:.3f} px\n", v.camera, v.view, v.rms_px);
    fmt::print("  {:.2f} s (detection {:.2f} s)\n", time_s, stats.detect_time_s);
  }
  return kExitYes;
}

}  // namespace

void add_calib_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  CLI::App* calib = app.add_subcommand("calib", "Calibrate cameras, arm and force sensors");
  calib->require_subcommand(1);

  auto args = std::make_shared<CamerasArgs>();
  CLI::App* c = calib->add_subcommand(
      "cameras",
      "Calibrate one camera or a rig from chessboard / ChArUco views: per-camera intrinsics, then "
      "a "
      "joint bundle adjustment over all cameras and board poses (cameras chained through shared "
      "views). Writes OpenCV FileStorage YAML.\nImages taken at the same moment by different "
      "cameras share the number in their file names (left03.jpg / right03.jpg).\nExit 0 written, "
      "2 bad input (unreadable images, no board found, no camera channel, too few views).");
  c->add_option("--pattern", args->pattern,
                "chessboard:COLSxROWS:SQUARE_M (inner corners, e.g. chessboard:9x6:0.025) or "
                "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT (squares)")
      ->required();
  c->add_option("--images", args->images, "CAMERA=GLOB, once per camera (first = rig frame)");
  c->add_option("--session", args->session, "Recorded session (.mcap) with camera channels");
  c->add_option("-o,--output", args->output, "Calibration file to write (.yml)")->required();
  c->add_flag("--fix-aspect-ratio", args->fix_aspect_ratio, "Estimate one focal length (fx = fy)");
  c->add_flag("--fix-k3", args->fix_k3, "Keep k3 = 0");
  c->add_flag("--zero-tangent", args->zero_tangent, "Keep p1 = p2 = 0");
  c->add_option("--loss", args->loss, "Robust loss of the joint adjustment: none, huber, cauchy")
      ->capture_default_str();
  c->add_option("--loss-scale", args->loss_scale_px, "Robust loss scale, px")
      ->capture_default_str();
  c->add_option("--outlier-factor", args->outlier_factor,
                "Flag views whose RMS exceeds this factor times the median view RMS")
      ->capture_default_str();
  c->add_flag("--json", args->json, "Print one JSON object");
  c->callback([&global, args, exit_code] { *exit_code = run_cameras(global, *args); });
}

HC_REGISTER_COMMANDS_ORDERED(40, add_calib_commands);

}  // namespace hc::cli
