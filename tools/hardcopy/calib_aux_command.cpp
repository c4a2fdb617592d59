// hardcopy calib hand-eye | ft-bias | fsr: the calibrations besides the cameras' (issue 5, item 2).
// Attached to the `calib` group that calib_command.cpp creates (registered at order 40; this file
// at 41, so the group exists by then).
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

#include "calibration/arm/hand_eye_session.h"
#include "calibration/force/force_session.h"
#include "calibration/force/fsr_fit.h"
#include "calibration/force/fsr_io.h"
#include "calibration/force/ft_bias.h"
#include "camera/camera_model.h"
#include "command.h"
#include "common/json.h"

namespace hc::cli {
namespace {

struct FtBiasArgs {
  std::string input;
  std::string device;
  double window_s = 0.1;
  double threshold_n = 0.25;
  bool json = false;
};

int run_ft_bias(const GlobalOptions& global, const FtBiasArgs& a) {
  Context ctx(global);
  calib::ForceSessionOptions so;
  so.ft_device = a.device;
  so.want_truth = false;
  if (auto* p = ctx.progress()) p->begin("read " + a.input, 0);
  auto session = calib::read_force_session(a.input, so);
  if (auto* p = ctx.progress()) p->end("");
  if (!session.ok()) return ctx.fail("calib ft-bias", session.status());
  calib::FtBiasOptions bo;
  bo.window_s = a.window_s;
  bo.contact_threshold_n = a.threshold_n;
  auto r = calib::estimate_ft_bias(session->wrench, bo);
  if (!r.ok()) return ctx.fail("calib ft-bias", r.status().with_context(a.input));
  if (a.json) {
    Json j = r->to_json();
    j["session"] = a.input;
    j["device"] = session->ft_device;
    if (!print_json(j).ok()) return kExitBadInput;
    return kExitYes;
  }
  fmt::print("{}: F/T '{}' bias from {} unloaded samples of {} ({} unloaded stretches, {:.1f} s)\n",
             a.input, session->ft_device, r->unloaded_samples, r->samples,
             r->unloaded_intervals_s.size(), r->duration_s);
  const char* axes[6] = {"Fx", "Fy", "Fz", "Tx", "Ty", "Tz"};
  for (int i = 0; i < 6; ++i) {
    const char* u = i < 3 ? "N" : "N·m";
    fmt::print("  {}  bias {:+.5f} ± {:.5f} {}   drift {:+.2e} ± {:.1e} {}/s   noise {:.4f} {}\n",
               axes[i], r->bias[i], r->bias_std[i], u, r->drift_per_s[i], r->drift_per_s_std[i], u,
               r->noise_std[i], u);
  }
  return kExitYes;
}

struct FsrArgs {
  std::string input;
  std::string output;
  std::string fsr_device;
  std::string ft_device;
  double min_force_n = 0.5;
  int knots = 8;
  bool json = false;
};

int run_fsr(const GlobalOptions& global, const FsrArgs& a) {
  Context ctx(global);
  calib::ForceSessionOptions so;
  so.ft_device = a.ft_device;
  so.fsr_device = a.fsr_device;
  so.want_fsr = true;
  if (auto* p = ctx.progress()) p->begin("read " + a.input, 0);
  auto session = calib::read_force_session(a.input, so);
  if (auto* p = ctx.progress()) p->end("");
  if (!session.ok()) return ctx.fail("calib fsr", session.status());
  auto bias = calib::estimate_ft_bias(session->wrench);
  if (!bias.ok())
    return ctx.fail("calib fsr", bias.status().with_context(a.input + ": F/T reference bias"));
  const std::vector<calib::FsrPair> pairs = calib::pair_fsr_with_ft(*session, *bias);
  calib::FsrFitOptions fo;
  fo.min_force_n = a.min_force_n;
  fo.knots = a.knots;
  if (session->recorded_fsr) fo.full_scale = session->recorded_fsr->full_scale;
  calib::FsrFitSummary summary;
  auto curve = calib::fit_fsr(pairs, fo, &summary);
  if (!curve.ok()) return ctx.fail("calib fsr", curve.status().with_context(a.input));
  curve->device = session->fsr_device;
  // Against the simulator's true force (simulated rigs): RMS of the fitted curve.
  double ss = 0.0;
  std::size_t n = 0;
  for (const calib::FsrReading& r : session->fsr) {
    const std::optional<double> t = calib::truth_force_at(*session, r.t_ns);
    if (!t || *t < fo.min_force_n) continue;
    const double e = curve->to_newtons(r.raw) - *t;
    ss += e * e;
    ++n;
  }
  if (Status s = calib::write_fsr_calibration(a.output, *curve); !s.ok())
    return ctx.fail("calib fsr", s);
  const calib::FsrFitQuality& q = curve->model == calib::FsrModel::kPowerLaw
                                      ? curve->power_law_quality
                                      : curve->piecewise_quality;
  if (a.json) {
    Json j = calib::fsr_curve_to_json(*curve);
    j["session"] = a.input;
    j["output"] = a.output;
    j["rms_n"] = q.rms_n;
    j["r2"] = q.r2;
    j["input_pairs"] = summary.input_pairs;
    j["time_s"] = summary.time_s;
    if (n > 0) j["truth_rms_error_n"] = std::sqrt(ss / static_cast<double>(n));
    if (session->recorded_fsr)
      j["recorded_calibration"] = {{"full_scale", session->recorded_fsr->full_scale},
                                   {"threshold", session->recorded_fsr->threshold},
                                   {"scale_n", session->recorded_fsr->scale_n},
                                   {"exponent", session->recorded_fsr->exponent}};
    if (!print_json(j).ok()) return kExitBadInput;
    return kExitYes;
  }
  fmt::print("{}: FSR '{}' against F/T '{}': {} pairs ({} loaded)\n", a.input, session->fsr_device,
             session->ft_device, summary.input_pairs, summary.loaded_pairs);
  const calib::FsrPowerLaw& p = curve->power_law;
  fmt::print(
      "  power law: threshold {:.5f} ± {:.5f}, scale {:.3f} ± {:.3f} N, exponent {:.4f} ± "
      "{:.4f}; RMS {:.4f} N, R² {:.6f}\n",
      p.threshold, curve->threshold_std, p.scale_n, curve->scale_n_std, p.exponent,
      curve->exponent_std, curve->power_law_quality.rms_n, curve->power_law_quality.r2);
  if (curve->piecewise.raw.size() >= 2)
    fmt::print("  piecewise linear ({} knots): RMS {:.4f} N, R² {:.6f}\n",
               curve->piecewise.raw.size(), curve->piecewise_quality.rms_n,
               curve->piecewise_quality.r2);
  fmt::print("  selected {} (lower BIC); wrote {}\n", calib::to_string(curve->model), a.output);
  if (n > 0)
    fmt::print("  against the simulator's true force: RMS {:.4f} N over {} readings\n",
               std::sqrt(ss / static_cast<double>(n)), n);
  return kExitYes;
}

struct HandEyeArgs {
  std::string input;
  std::string calib;
  std::string output;
  std::string arm_device;
  double marker0_z_m = 0.06;
  bool json = false;
};

int run_hand_eye(const GlobalOptions& global, const HandEyeArgs& a) {
  Context ctx(global);
  auto rig = read_rig_calibration(a.calib);
  if (!rig.ok()) return ctx.fail("calib hand-eye", rig.status());
  calib::HandEyeSessionOptions o;
  o.arm_device = a.arm_device;
  o.marker0_tool_z_m = a.marker0_z_m;
  if (auto* p = ctx.progress()) p->begin("hand-eye " + a.input, 0);
  auto r = calib::calibrate_hand_eye_from_session(a.input, *rig, o);
  if (auto* p = ctx.progress()) p->end("");
  if (!r.ok()) return ctx.fail("calib hand-eye", r.status());
  RigCalibration out = *rig;
  out.world_from_rig = r->solution.world_from_rig;
  if (Status s = write_rig_calibration(a.output, out); !s.ok())
    return ctx.fail("calib hand-eye", s);
  if (a.json) {
    Json j = r->to_json();
    j["session"] = a.input;
    j["output"] = a.output;
    if (!print_json(j).ok()) return kExitBadInput;
    return kExitYes;
  }
  const calib::HandEyeResult& s = r->solution;
  const Eigen::Vector3d t = s.world_from_rig.translation();
  fmt::print("{}: hand-eye from {} of {} steps ({} observations; rotations: {})\n", a.input,
             r->steps_used, r->steps, s.observations, s.rotation_excitation);
  fmt::print("  world_from_rig: t = [{:.5f}, {:.5f}, {:.5f}] m ± [{:.2e}, {:.2e}, {:.2e}]\n", t.x(),
             t.y(), t.z(), s.translation_std_m.x(), s.translation_std_m.y(),
             s.translation_std_m.z());
  fmt::print("  rotation std [{:.4f}, {:.4f}, {:.4f}] deg; residual RMS {:.4f} mm (max {:.4f})\n",
             s.rotation_std_rad.x() * 180.0 / std::numbers::pi,
             s.rotation_std_rad.y() * 180.0 / std::numbers::pi,
             s.rotation_std_rad.z() * 180.0 / std::numbers::pi, s.rms_m * 1e3, s.max_m * 1e3);
  fmt::print("  constraint: {}\n", s.constraint);
  if (r->has_truth)
    fmt::print("  against the simulator's truth: RMS {:.4f} mm, max {:.4f} mm\n",
               r->truth_rms_m * 1e3, r->truth_max_m * 1e3);
  fmt::print("  wrote {}\n", a.output);
  return kExitYes;
}

}  // namespace

void add_calib_aux_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  // CLI11 2.1.2 has no get_subcommand_no_throw (get_subcommand throws): find the group by name.
  auto found = app.get_subcommands([](CLI::App* s) { return s->get_name() == "calib"; });
  CLI::App* calib = found.empty() ? app.add_subcommand("calib",
                                                       "Calibrate cameras, arm and force "
                                                       "sensors")
                                  : found.front();
  calib->require_subcommand(1);

  auto fb = std::make_shared<FtBiasArgs>();
  CLI::App* f = calib->add_subcommand(
      "ft-bias",
      "Six-axis F/T bias and drift from the unloaded stretches of a session's wrench channel "
      "(windows' median/MAD, line fit, least squares with standard errors).\nExit 0 on success, 1 "
      "when no unloaded stretch is found, 2 on bad input (unreadable session, no F/T channel).");
  f->add_option("SESSION", fb->input, "Session file (.mcap)")->required();
  f->add_option("--device", fb->device, "F/T device name (default: the first F/T channel)");
  f->add_option("--window", fb->window_s, "Analysis window, s")
      ->check(kPositive)
      ->capture_default_str();
  f->add_option("--threshold", fb->threshold_n, "Loaded when farther than this from the bias, N")
      ->check(kPositive)
      ->capture_default_str();
  f->add_flag("--json", fb->json, "Print one JSON object");
  f->callback([&global, fb, exit_code] { *exit_code = run_ft_bias(global, *fb); });

  auto fs = std::make_shared<FsrArgs>();
  CLI::App* r = calib->add_subcommand(
      "fsr",
      "FSR response curve (raw -> N) fitted against the F/T sensor: power law (threshold, scale, "
      "exponent; Ceres) and a monotone piecewise-linear curve, selected by BIC. Writes the FSR "
      "JSON file (calibration/force/fsr_io.h).\nExit 0 on success, 1 when the session cannot "
      "support a fit (too few loaded pairs), 2 on bad input.");
  r->add_option("SESSION", fs->input, "Session file (.mcap) with FSR and F/T channels")->required();
  r->add_option("-o,--output", fs->output, "FSR calibration to write (.json)")->required();
  r->add_option("--fsr", fs->fsr_device, "FSR device name (default: the first FSR channel)");
  r->add_option("--ft", fs->ft_device, "F/T device name (default: the first F/T channel)");
  r->add_option("--min-force", fs->min_force_n, "Pairs with less reference force are not fitted, N")
      ->check(kNonNegative)
      ->capture_default_str();
  r->add_option("--knots", fs->knots, "Knots of the piecewise-linear curve")
      ->check(CLI::Range(2, 64))
      ->capture_default_str();
  r->add_flag("--json", fs->json, "Print one JSON object");
  r->callback([&global, fs, exit_code] { *exit_code = run_fsr(global, *fs); });

  auto he = std::make_shared<HandEyeArgs>();
  CLI::App* h = calib->add_subcommand(
      "hand-eye",
      "Arm <-> camera rig (world_from_rig) from the probe's two shaft markers triangulated at the "
      "arm poses of a session (Umeyama + Ceres, robust loss). Writes CALIB with world_from_rig "
      "set; with simulator truth in the session --json adds truth_rms_error_m.\nExit 0 on "
      "success, 1 when the poses leave it unobservable, 2 on bad input.");
  h->add_option("SESSION", he->input, "Session file (.mcap) with arm states and camera frames")
      ->required();
  h->add_option("--calib", he->calib, "Camera calibration (.yml, from `calib cameras`)")
      ->required();
  h->add_option("-o,--output", he->output, "Calibration to write with world_from_rig set")
      ->required();
  h->add_option("--arm", he->arm_device, "Arm device name (default: the first arm)");
  h->add_option("--marker0-z", he->marker0_z_m,
                "Distance of the shaft marker nearer the tip from the tip along the shaft, m "
                "(unobservable with a yaw-only arm)")
      ->capture_default_str();
  h->add_flag("--json", he->json, "Print one JSON object");
  h->callback([&global, he, exit_code] { *exit_code = run_hand_eye(global, *he); });
}

HC_REGISTER_COMMANDS_ORDERED(41, add_calib_aux_commands);

}  // namespace hc::cli
