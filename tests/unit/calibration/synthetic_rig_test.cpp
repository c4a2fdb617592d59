// Synthetic rigs with known truth (calibration/cameras/synthetic.h): the solver alone on projected
// corners with Gaussian noise, and the whole pipeline on rendered, anti-aliased board images.
//
// Issue 5: "3 and 7 cameras on a half circle, 1600 x 1200, 0.1-0.3 px corner noise: focal lengths
// within 0.1 %, camera centres within 0.1 mm, joint RMS consistent with the injected noise".
//
// Geometry. The accuracy cases use the product's capture geometry (synthetic.h
// capture_rig_options, = rig_daemon/examples/rig_sim_hires.yaml after thesis Sec. 5.6: cameras
// 0.294 m from a ~50 mm specimen on a half circle 41.6 deg above it, f = 3500 px, a 0.137 x 0.103 m
// view) with a board sized for that view (capture_board: 15 x 10 corners, 5 mm squares) in poses
// tilted 20-50 deg through a +-20 mm working volume (capture_board_poses). The former cases
// (radius 1 m, f = 1800 px, 9 x 6 board of 50 mm squares, tilts +-35 deg per axis: 0.5-5 mm)
// are kept as one far case documenting the scaling: at a fixed pixel footprint every metric
// error scales with the size of the scene (board 50 -> 5 mm squares), 2.8 mm there (0.1 px, 40
// poses) against 0.04-0.07 mm here.
//
// What limits the centres (explored with 3-6 seeds per setting; the errors agree with the Ceres
// covariance within 2 sigma, so they are information-limited, not solver-limited):
// * Depth x focal error. A camera's centre error is mostly along its optical axis: a relative
//   focal error df/f moves it by ~ depth x df/f (0.294 m x 0.03 % = 0.09 mm). After rigid
//   alignment (below) the axial part was 0.03-0.07 mm and the lateral part 0.01-0.03 mm at
//   0.1 px / 40 poses. Near-frontal poses (tilts drawn +-35 deg per axis) gave ~2x the focal
//   error, a 9 x 6 board of 8 mm squares (rigd's calibration_board.yaml) ~0.25 mm, a 13 x 9 board
//   of 6 mm ~1.5x ours; drawing the faced camera uniformly (not neighbour pairs) gives the arc's
//   end cameras as many views as the others. Tilts of 35-55 or 30-60 deg were no better than
//   20-50; fixing k3 changed nothing.
// * Noise and poses: errors go as sigma / sqrt(poses); 7 cameras at 0.3 px with 40 poses gave
//   0.175 mm RMS (worst 0.22 mm, 6 seeds), 120 poses 0.07-0.14 mm, 300 poses 0.054 mm (the CI
//   case, ~8 s); bench_calibration BM_CaptureRigSolverNoise03/500: 0.055 mm gauge-free, 0.114 mm
//   raw.
// * Gauge. calibrate_rig's centres are relative to camera 0. At f = 3500 px (a 26 deg field of
//   view) a shift of camera 0's principal point by d px is nearly indistinguishable from turning
//   it by d / f: its cx, cy are only known to 1.5-3 px (1 sigma at 0.1-0.3 px noise), i.e.
//   0.4-0.9 mrad, which swings camera 6 (0.44 m away) by 0.2-0.4 mm. That raw error moves the
//   whole rig rigidly, which triangulation does not see (the mesh registration fixes the world
//   frame), so the 0.1 mm criterion is asserted on the gauge-free error: the worst centre after
//   the best rigid alignment of all recovered centres onto the true ones (compare_centres). The
//   raw error is asserted too: per axis within 4 predicted standard deviations, and below 0.5 mm
//   (1 mm at 0.3 px; measured 0.11-0.58 mm); 0.1 mm raw would need camera 0's principal point to
//   ~0.25 px, ~50x more corner observations.
// * Solver: Ceres converges (function tolerance) in 10-13 iterations, every view is kept (none
//   flagged an outlier) and the joint RMS matches sigma sqrt((2N - p) / 2N) within 1.3 %.
// Results here (Release): 3 cameras 0.2 px 60 poses 0.027 mm gauge-free / 0.12 mm raw; 7 cameras
// 0.1 px 60 poses 0.054 / 0.11 mm; 7 cameras 0.3 px 300 poses 0.054 / 0.37 mm; rendered images
// (3 cameras, 12 poses, detection error ~0.06 px RMS) 0.032 / 0.065 mm.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "calibration/cameras/board.h"
#include "calibration/cameras/calibrate.h"
#include "calibration/cameras/synthetic.h"
#include "sanitizer.h"

namespace hc::calib {
namespace {

BoardSpec synthetic_board() { return *parse_board_spec("chessboard:9x6:0.05"); }

struct Errors {
  double focal_rel = 0.0;     // worst |f - f_true| / f_true over fx, fy
  double centre_m = 0.0;      // worst camera centre error
  double principal_px = 0.0;  // worst principal point error
};

Errors compare(const std::vector<CameraModel>& truth, const RigCalibration& got) {
  Errors e;
  EXPECT_EQ(truth.size(), got.cameras.size());
  for (std::size_t i = 0; i < truth.size() && i < got.cameras.size(); ++i) {
    const CameraModel& t = truth[i];
    const CameraModel& g = got.cameras[i];
    e.focal_rel =
        std::max({e.focal_rel, std::abs(g.fx - t.fx) / t.fx, std::abs(g.fy - t.fy) / t.fy});
    e.centre_m = std::max(e.centre_m, (g.center_m() - t.center_m()).norm());
    e.principal_px = std::max(e.principal_px, std::hypot(g.cx - t.cx, g.cy - t.cy));
  }
  return e;
}

// Expected joint RMS for residuals of per-coordinate sigma: sqrt(2 sigma^2 (2N - p) / (2N)) for
// N corner observations and p free parameters (least squares removes p degrees of freedom).
double expected_rms(double sigma, const CalibrationSummary& s, int cameras, bool fix_aspect) {
  const int p = cameras * (fix_aspect ? 8 : 9) + 6 * (cameras - 1) + 6 * s.board_poses;
  const double n2 = 2.0 * s.observations;
  return sigma * std::sqrt(2.0 * (n2 - p) / n2);
}

struct Case {
  int cameras = 7;
  double sigma = 0.1;  // px per coordinate
  int poses = 40;
  std::uint32_t seed = 1;
  bool capture = true;  // the capture geometry (header); false: the far rig (1 m, f 1800 px)
  // Capture geometry: the 0.1 mm criterion on the gauge-free centre error, a bound on the raw one.
  double aligned_max_m = 0.1e-3;
  double raw_max_m = 0.5e-3;
};

// Solver alone: noisy projections. Truth: the generator's cameras.
void solver_case(const Case& k) {
  const SyntheticRigOptions ro = k.capture ? capture_rig_options(k.cameras) : [&] {
    SyntheticRigOptions o;
    o.cameras = k.cameras;
    return o;
  }();
  const BoardSpec b = k.capture ? capture_board() : synthetic_board();
  const std::vector<CameraModel> truth = make_half_circle_rig(ro);
  BoardPoseOptions po = capture_board_poses(k.poses, k.seed);
  // Seven cameras: the arc's ends never see the board together (issue 5).
  if (k.cameras == 7) po.max_camera_span = 6;
  const std::vector<Eigen::Isometry3d> P =
      k.capture ? random_board_poses(truth, b, po) : random_board_poses(truth, b, k.poses, k.seed);
  ASSERT_EQ(static_cast<int>(P.size()), k.poses);
  const std::vector<CameraObservations> obs =
      synthetic_observations(truth, b, P, k.sigma, k.seed + 1);
  int camera_views = 0;
  for (const CameraObservations& o : obs) camera_views += static_cast<int>(o.views.size());
  if (k.cameras == 7) {
    // Issue 5: some cameras never co-observe the board with each other (the arc's ends).
    std::vector<std::set<int>> seen(obs.size());
    for (std::size_t c = 0; c < obs.size(); ++c)
      for (const ViewObservation& v : obs[c].views) seen[c].insert(v.view);
    int never_pairs = 0, never_with_0 = 0;
    for (std::size_t a = 0; a < obs.size(); ++a)
      for (std::size_t c = a + 1; c < obs.size(); ++c) {
        bool shared = false;
        for (int v : seen[a]) shared = shared || seen[c].count(v) > 0;
        never_pairs += shared ? 0 : 1;
        never_with_0 += a == 0 && !shared ? 1 : 0;
      }
    EXPECT_GE(never_pairs, 1) << "the arc's far ends should never see a board together";
    if (!k.capture) {
      EXPECT_GE(never_with_0, 2) << "far rig: some cameras never with camera 0";
    }
  }
  const CalibrationOptions options;
  Result<CalibrationSummary> s = calibrate_rig(obs, b, options);
  ASSERT_TRUE(s.ok()) << s.status().message();
  const Errors e = compare(truth, s->rig);
  const CentreErrors ce = compare_centres(truth, s->rig.cameras);
  const double rms_expect = expected_rms(k.sigma, *s, k.cameras, false);
  std::printf(
      "  %s, %d cameras, sigma %.2f px, %d poses (%d camera views): focal err %.4f %%, centre "
      "err raw %.4f mm, aligned %.4f mm (axial %.4f, lateral %.4f), principal %.3f px, joint RMS "
      "%.4f px (expected %.4f), %d iterations, %.2f s\n",
      k.capture ? "capture rig" : "far rig", k.cameras, k.sigma, k.poses, camera_views,
      100 * e.focal_rel, 1e3 * ce.raw_m, 1e3 * ce.aligned_m, 1e3 * ce.aligned_axial_m,
      1e3 * ce.aligned_lateral_m, e.principal_px, s->joint_rms_px, rms_expect, s->iterations,
      s->init_time_s + s->solve_time_s + s->covariance_time_s);
  // The bundle adjustment ran to convergence (a tolerance, not the iteration limit).
  EXPECT_TRUE(s->converged) << s->termination;
  EXPECT_LT(s->iterations, options.max_iterations);
  // Every view is used and none is flagged: the noise is Gaussian, there is nothing to reject.
  EXPECT_EQ(static_cast<int>(s->views.size()), camera_views);
  EXPECT_TRUE(s->outliers().empty());
  // Issue 5: focal lengths within 0.1 %.
  EXPECT_LT(e.focal_rel, 1e-3);
  if (k.sigma == 0.0) {
    EXPECT_LT(s->joint_rms_px, 1e-9);
    EXPECT_LT(e.centre_m, 1e-6);  // exact data: exact answer
    return;
  }
  // Joint RMS consistent with the injected noise: with >= 10^4 residuals the RMS itself varies by
  // < 0.5 % (1 sigma), so 3 %.
  EXPECT_NEAR(s->joint_rms_px, rms_expect, 0.03 * rms_expect);
  // Each estimate within 4 predicted standard deviations (Ceres covariance) of the truth, and the
  // predicted deviations realistic (not inflated beyond 5 mm).
  for (std::size_t c = 0; c < truth.size(); ++c) {
    const CameraReport& r = s->cameras[c];
    const CameraModel& g = s->rig.cameras[c];
    ASSERT_EQ(r.intrinsics_std.size(), 9u);
    ASSERT_EQ(r.center_std_m.size(), 3u);
    EXPECT_LT(std::abs(g.fx - truth[c].fx), 4 * r.intrinsics_std[0]) << truth[c].name;
    EXPECT_LT(std::abs(g.cx - truth[c].cx), 4 * r.intrinsics_std[2]) << truth[c].name;
    EXPECT_LT(std::abs(g.cy - truth[c].cy), 4 * r.intrinsics_std[3]) << truth[c].name;
    const Eigen::Vector3d d = g.center_m() - truth[c].center_m();
    for (int i = 0; i < 3; ++i) {
      EXPECT_LE(std::abs(d(i)), 4 * r.center_std_m[static_cast<std::size_t>(i)] + 1e-12)
          << truth[c].name << " axis " << i;
      EXPECT_LT(r.center_std_m[static_cast<std::size_t>(i)], 5e-3) << truth[c].name;
    }
  }
  if (k.capture) {
    // Issue 5: camera centres within 0.1 mm, gauge-free (header: why; 0.3 px: see its case), and
    // the raw error relative to camera 0 below 0.5 mm.
    EXPECT_LT(ce.aligned_m, k.aligned_max_m);
    EXPECT_LT(ce.raw_m, k.raw_max_m);
  }
}

// The far rig, exact corners: the solver recovers the truth exactly.
TEST(SyntheticRig, SevenCamerasSolverExactData) {
  solver_case({.cameras = 7, .sigma = 0.0, .poses = 30, .seed = 41, .capture = false});
}
// The far rig with noise (scaling; header): 4-sigma checks only.
TEST(SyntheticRig, FarSevenCamerasSomeNeverSeeCameraZero) {
  solver_case({.cameras = 7, .sigma = 0.1, .poses = 40, .seed = 21, .capture = false});
}

// The capture geometry: issue 5's criteria.
TEST(SyntheticRig, CaptureThreeCamerasNoise02) {
  solver_case({.cameras = 3, .sigma = 0.2, .poses = 60, .seed = 11});
}
TEST(SyntheticRig, CaptureSevenCamerasNoise01) {
  HC_SKIP_WHEN_SANITIZED("~1 min: 7 cameras rendered and adjusted");
  solver_case({.cameras = 7, .sigma = 0.1, .poses = 60, .seed = 21});
}
// At 0.3 px the 0.1 mm needs a few hundred poses (header: 40 poses gave 0.175 mm RMS over 6 seeds,
// errors go as 1 / sqrt(poses)). 300 poses: 0.054 mm gauge-free, 0.37 mm raw (200 poses: 0.066 /
// 0.54 mm); ~8 s in Release, most of it the covariance.
TEST(SyntheticRig, CaptureSevenCamerasNoise03) {
  HC_SKIP_WHEN_SANITIZED("~2 min: 7 cameras rendered and adjusted");
  solver_case({.cameras = 7,
               .sigma = 0.3,
               .poses = 300,
               .seed = 31,
               .capture = true,
               .aligned_max_m = 0.1e-3,
               .raw_max_m = 1.0e-3});
}

// A chessboard with cols + rows even (8x6) is half-turn symmetric: cameras may number its corners
// in opposite orders. Reverse the numbering in half of cameras 1 and 2's views; calibrate_rig must
// match them to camera 0's through the visibility graph and still recover the truth.
TEST(SyntheticRig, SymmetricBoardMixedCornerOrder) {
  const BoardSpec sym = *parse_board_spec("chessboard:8x6:0.05");
  SyntheticRigOptions ro;
  ro.cameras = 3;
  ro.arc_deg = 60.0;
  const std::vector<CameraModel> truth = make_half_circle_rig(ro);
  const auto P = random_board_poses(truth, sym, 20, 99, 2);
  std::vector<CameraObservations> obs = synthetic_observations(truth, sym, P, 0.1, 100);
  int reversed = 0;
  for (std::size_t c = 1; c < obs.size(); ++c)
    for (std::size_t v = 0; v < obs[c].views.size(); v += 2) {
      std::reverse(obs[c].views[v].pixels.begin(), obs[c].views[v].pixels.end());
      ++reversed;
    }
  ASSERT_GT(reversed, 5);
  Result<CalibrationSummary> s = calibrate_rig(obs, sym, {});
  ASSERT_TRUE(s.ok()) << s.status().message();
  const Errors e = compare(truth, s->rig);
  EXPECT_LT(e.focal_rel, 1e-3);
  EXPECT_NEAR(s->joint_rms_px, expected_rms(0.1, *s, 3, false),
              0.2 * expected_rms(0.1, *s, 3, false));
  EXPECT_TRUE(s->outliers().empty());
}

TEST(SyntheticRig, OutlierViewFlagged) {
  SyntheticRigOptions ro;
  ro.cameras = 2;
  ro.arc_deg = 40.0;
  const std::vector<CameraModel> truth = make_half_circle_rig(ro);
  const auto P = random_board_poses(truth, synthetic_board(), 12, 5);
  std::vector<CameraObservations> obs = synthetic_observations(truth, synthetic_board(), P, 0.1, 6);
  // Corrupt one view of camera 1 by 3 px of structured error.
  ViewObservation& bad = obs[1].views[3];
  for (std::size_t i = 0; i < bad.pixels.size(); ++i) bad.pixels[i].x() += (i % 2 ? 3.0 : -3.0);
  Result<CalibrationSummary> s = calibrate_rig(obs, synthetic_board(), {});
  ASSERT_TRUE(s.ok()) << s.status().message();
  const auto out = s->outliers();
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].camera, "cam1");
  EXPECT_EQ(out[0].view, bad.view);
  // A robust loss keeps the corrupted view from pulling the focal length.
  CalibrationOptions robust;
  robust.loss = RobustLoss::kHuber;
  robust.loss_scale_px = 0.5;
  Result<CalibrationSummary> r = calibrate_rig(obs, synthetic_board(), robust);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(compare(truth, r->rig).focal_rel, compare(truth, s->rig).focal_rel + 1e-4);
}

TEST(SyntheticRig, DisconnectedCameraIsAnError) {
  SyntheticRigOptions ro;
  ro.cameras = 2;
  const auto truth = make_half_circle_rig(ro);
  auto obs = synthetic_observations(truth, synthetic_board(),
                                    random_board_poses(truth, synthetic_board(), 10, 3, 1), 0.0, 1);
  // Renumber camera 1's views so none is shared with camera 0.
  for (ViewObservation& v : obs[1].views) v.view += 1000;
  Result<CalibrationSummary> s = calibrate_rig(obs, synthetic_board(), {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("cam1"), std::string::npos) << s.status().message();
  // Too few views.
  obs[1].views.resize(2);
  for (ViewObservation& v : obs[1].views) v.view -= 1000;
  s = calibrate_rig(obs, synthetic_board(), {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("cam1"), std::string::npos);
}

// Rendered images through the true model, detected with OpenCV: the whole pipeline, at the capture
// geometry (header) and full resolution. CI size: 3 cameras, 12 poses; bench_calibration renders
// 7 cameras x 30 poses (0.016 mm gauge-free, 0.064 mm raw).
TEST(SyntheticRig, CaptureThreeCamerasRenderedImages) {
  HC_SKIP_WHEN_SANITIZED("~2 min: rendered images detected");
  const std::vector<CameraModel> truth = make_half_circle_rig(capture_rig_options(3));
  const BoardSpec b = capture_board();
  const auto P = random_board_poses(truth, b, capture_board_poses(12, 77));
  ASSERT_EQ(P.size(), 12u);
  std::vector<CameraObservations> obs;
  double worst_corner = 0.0;
  int detected = 0, visible = 0;
  for (const CameraModel& cam : truth) {
    ChessboardRenderer renderer(cam, b);
    CameraObservations o{cam.name, cam.width, cam.height, {}};
    for (std::size_t v = 0; v < P.size(); ++v) {
      if (!board_visible(cam, b, P[v])) continue;
      ++visible;
      const std::vector<std::uint8_t> img = renderer.render(P[v]);
      ImageView view{cam.width, cam.height, cam.width, 1, img.data()};
      Result<std::optional<BoardDetection>> d = detect_board(view, b);
      ASSERT_TRUE(d.ok());
      if (!d->has_value()) continue;
      ++detected;
      for (std::size_t i = 0; i < (*d)->ids.size(); ++i)
        worst_corner = std::max(
            worst_corner, ((*d)->pixels[i] - *cam.project(P[v] * b.corner((*d)->ids[i]))).norm());
      o.views.push_back({static_cast<int>(v), (*d)->ids, (*d)->pixels});
    }
    obs.push_back(std::move(o));
  }
  EXPECT_EQ(detected, visible);
  // Sub-pixel corners on anti-aliased renders: well under a pixel, and in the right (canonical)
  // order in every camera (a half-turned board would be tens of pixels off).
  EXPECT_LT(worst_corner, 0.3);
  Result<CalibrationSummary> s = calibrate_rig(obs, b, {});
  ASSERT_TRUE(s.ok()) << s.status().message();
  const Errors e = compare(truth, s->rig);
  const CentreErrors ce = compare_centres(truth, s->rig.cameras);
  std::printf(
      "  rendered: %d views detected, worst corner %.3f px, focal err %.4f %%, centre err raw "
      "%.4f mm, aligned %.4f mm, joint RMS %.4f px, %.2f s\n",
      detected, worst_corner, 100 * e.focal_rel, 1e3 * ce.raw_m, 1e3 * ce.aligned_m,
      s->joint_rms_px, s->init_time_s + s->solve_time_s + s->covariance_time_s);
  EXPECT_TRUE(s->converged) << s->termination;
  EXPECT_LT(e.focal_rel, 1e-3);
  EXPECT_LT(s->joint_rms_px, 0.15);
  EXPECT_TRUE(s->outliers().empty());
  // Issue 5's 0.1 mm, gauge-free and (with rendered corners' ~0.05 px error) raw too.
  EXPECT_LT(ce.aligned_m, 0.1e-3);
  EXPECT_LT(ce.raw_m, 0.1e-3);
  for (std::size_t c = 1; c < truth.size(); ++c) {
    const Eigen::Vector3d d = s->rig.cameras[c].center_m() - truth[c].center_m();
    for (int k = 0; k < 3; ++k)
      EXPECT_LE(std::abs(d(k)), 4 * s->cameras[c].center_std_m[static_cast<std::size_t>(k)])
          << truth[c].name << " axis " << k;
  }
}

}  // namespace
}  // namespace hc::calib
