// End to end on the simulated rig: rigd's daemon records the example calibration capture
// (rig_daemon/examples/calibration_board.yaml: 9x6 inner corners, 8 mm squares, 20 poses) on the
// high-resolution example rig (rig_daemon/examples/rig_sim_hires.yaml: seven 1600x1200 cameras,
// f = 3500 px, each with its own distortion and principal point), then `hardcopy calib cameras
// --session` calibrates it; the session's "sim_cameras" metadata holds the true parameters
// (rig_daemon/session/topics.h), expressed in the world frame.
#include <gtest/gtest.h>

#include <algorithm>

#include <nlohmann/json.hpp>

#include "calibration/cameras/synthetic.h"
#include "camera/camera_model.h"
#include "cli_run.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"
#include "sanitizer.h"
#include "sim_session.h"
#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::ScratchDir;

// Tolerances: 0.05 % in focal length, issue 5's 0.1 mm on the camera centres after the best rigid
// alignment onto the truth (the gauge-free error; measured 0.023 mm), and 0.5 mm on the raw centres
// relative to camera 0 (measured 0.305 mm) — the simulator renders the board through the exact
// model with anti-aliased edges (corner error < 0.05 px mean, SIMRIG's sim_scene_test), so the
// remaining error is detection noise over 20 poses, and at f = 3500 px camera 0's principal point
// is nearly indistinguishable from its orientation, which swings the whole rig about camera 0
// (synthetic_rig_test.cpp's header).
TEST(SimRigSession, CalibrationCaptureRecoversTrueCameras) {
  HC_SKIP_WHEN_SANITIZED("~3 min: a rendered 7-camera capture");
  ScratchDir dir;
  Result<rig::RigConfig> cfg =
      rig::load_rig_config(hc::testing::source_dir() / "rig_daemon/examples/rig_sim_hires.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
  Result<rig::Plan> plan =
      rig::load_plan(hc::testing::source_dir() / "rig_daemon/examples/calibration_board.yaml");
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  Result<std::filesystem::path> recorded =
      hc::testing::record_simulated_session(*cfg, *plan, dir.path(), 900000);
  ASSERT_TRUE(recorded.ok()) << recorded.status().to_string();
  const std::string session = recorded->string();
  // Truth: the simulated cameras in camera 0's frame.
  Result<RigCalibration> truth = hc::testing::true_rig_of_session(*recorded);
  ASSERT_TRUE(truth.ok()) << truth.status().to_string();

  const auto out = dir / "rig.yml";
  const auto r = hc::testing::hardcopy("calib cameras --pattern chessboard:9x6:0.008 --session " +
                                       session + " -o " + out.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << hc::testing::run_command(
                                   (hc::testing::bin_dir() / "hardcopy").string() +
                                   " --quiet calib cameras --pattern "
                                   "chessboard:9x6:0.008 --session " +
                                   session + " -o " + out.string() + " 2>&1")
                                   .out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  Result<RigCalibration> rig = read_rig_calibration(out);
  ASSERT_TRUE(rig.ok());
  // Our rig frame is camera 0's, as the truth's.
  ASSERT_EQ(rig->cameras[0].name, truth->cameras[0].name);
  double worst_f = 0.0, worst_c = 0.0;
  std::vector<CameraModel> truth_rig;  // true cameras in calibration order (compare_centres)
  for (const CameraModel& g : rig->cameras) {
    const auto t = std::find_if(truth->cameras.begin(), truth->cameras.end(),
                                [&](const CameraModel& c) { return c.name == g.name; });
    ASSERT_NE(t, truth->cameras.end()) << g.name;
    worst_f = std::max({worst_f, std::abs(g.fx - t->fx) / t->fx, std::abs(g.fy - t->fy) / t->fy});
    worst_c = std::max(worst_c, (g.center_m() - t->center_m()).norm());
    truth_rig.push_back(*t);
  }
  const CentreErrors ce = compare_centres(truth_rig, rig->cameras);
  std::printf(
      "  sim rig: %zu cameras, joint RMS %.4f px, worst focal error %.3f %%, worst centre "
      "error %.3f mm raw, %.3f mm after rigid alignment (axial %.3f, lateral %.3f)\n",
      rig->cameras.size(), j["joint_rms_px"].get<double>(), 100 * worst_f, 1e3 * worst_c,
      1e3 * ce.aligned_m, 1e3 * ce.aligned_axial_m, 1e3 * ce.aligned_lateral_m);
  EXPECT_EQ(rig->cameras.size(), truth->cameras.size());
  EXPECT_LT(worst_f, 5e-4);
  EXPECT_LT(worst_c, 0.5e-3);
  EXPECT_LT(ce.aligned_m, 0.1e-3);
  EXPECT_LT(j["joint_rms_px"].get<double>(), 0.1);
}

}  // namespace
}  // namespace hc::calib
