// Calibration of a 7-camera rig from 30 board poses (issue 5 speed target: <= 30 s on the 2-core
// machine): cameras on a half circle, 1600x1200, a 9x6 chessboard rendered (anti-aliased, through
// the true distortion) into every camera's image for every pose, then
//   stage 1: board detection on all 210 images (OpenCV findChessboardCorners + cornerSubPix),
//   stage 2: the joint bundle adjustment (per-camera OpenCV init, visibility graph, Ceres,
//   covariance).
// For comparison in the same run: OpenCV's own calibrateCamera on each camera plus stereoCalibrate
// on each chained pair (OpenCV has no multi-camera calibration), on the same detections.
// Counters: detect_s, ba_s, total_s, opencv_s, ratio_vs_opencv, joint_rms_px, focal_err_pct,
// centre_err_mm (render_s is set-up, not timed).
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>

#include "calibration/cameras/board.h"
#include "calibration/cameras/calibrate.h"
#include "calibration/cameras/synthetic.h"

namespace {

using hc::calib::BoardSpec;
using hc::calib::CameraModel;
using hc::calib::CameraObservations;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void BM_SevenCameraRig30Poses(benchmark::State& state) {
  const BoardSpec board = *hc::calib::parse_board_spec("chessboard:9x6:0.05");
  hc::calib::SyntheticRigOptions ro;
  ro.cameras = 7;
  const std::vector<CameraModel> truth = hc::calib::make_half_circle_rig(ro);
  const auto poses = hc::calib::random_board_poses(truth, board, 30, 2024, 2);
  // Render every camera x pose (what a capture would record).
  const auto t_render = Clock::now();
  std::vector<std::vector<std::vector<std::uint8_t>>> images(truth.size());
  for (std::size_t c = 0; c < truth.size(); ++c) {
    hc::calib::ChessboardRenderer r(truth[c], board);
    for (const auto& p : poses) images[c].push_back(r.render(p));
  }
  const double render_s = since(t_render);

  for (auto _ : state) {
    const auto t0 = Clock::now();
    std::vector<CameraObservations> obs;
    for (std::size_t c = 0; c < truth.size(); ++c) {
      CameraObservations o{truth[c].name, truth[c].width, truth[c].height, {}};
      for (std::size_t v = 0; v < poses.size(); ++v) {
        hc::calib::ImageView view{truth[c].width, truth[c].height, truth[c].width, 1,
                                  images[c][v].data()};
        auto d = hc::calib::detect_board(view, board);
        if (d.ok() && d->has_value())
          o.views.push_back({static_cast<int>(v), (*d)->ids, (*d)->pixels});
      }
      obs.push_back(std::move(o));
    }
    const double detect_s = since(t0);
    const auto t1 = Clock::now();
    auto s = hc::calib::calibrate_rig(obs, board, {});
    const double ba_s = since(t1);
    if (!s.ok()) {
      state.SkipWithError(s.status().message().c_str());
      return;
    }
    // OpenCV on the same detections: calibrateCamera per camera, stereoCalibrate per chained pair.
    const auto t2 = Clock::now();
    for (const auto& o : obs)
      benchmark::DoNotOptimize(hc::calib::calibrate_camera_opencv(o, board));
    for (std::size_t c = 1; c < obs.size(); ++c) {
      std::size_t parent = 0;
      for (std::size_t k = 0; k < obs.size(); ++k)
        if (obs[k].name == s->cameras[c].parent) parent = k;
      benchmark::DoNotOptimize(hc::calib::stereo_calibrate_opencv(obs[parent], obs[c], board));
    }
    const double opencv_s = since(t2);
    double focal = 0.0, centre = 0.0;
    int views = 0;
    for (std::size_t c = 0; c < truth.size(); ++c) {
      focal = std::max(focal, std::abs(s->rig.cameras[c].fx - truth[c].fx) / truth[c].fx);
      centre = std::max(centre, (s->rig.cameras[c].center_m() - truth[c].center_m()).norm());
      views += static_cast<int>(obs[c].views.size());
    }
    state.counters["render_s"] = render_s;
    state.counters["detect_s"] = detect_s;
    state.counters["ba_s"] = ba_s;
    state.counters["ba_solve_s"] = s->solve_time_s;
    state.counters["ba_covariance_s"] = s->covariance_time_s;
    state.counters["total_s"] = detect_s + ba_s;
    state.counters["opencv_s"] = opencv_s;
    state.counters["ratio_vs_opencv"] = ba_s / opencv_s;
    state.counters["joint_rms_px"] = s->joint_rms_px;
    state.counters["focal_err_pct"] = 100.0 * focal;
    state.counters["centre_err_mm"] = 1e3 * centre;
    state.counters["camera_views"] = views;
    state.counters["images"] = static_cast<double>(truth.size() * poses.size());
  }
}
BENCHMARK(BM_SevenCameraRig30Poses)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
