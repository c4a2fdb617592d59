// Tracking speed, the number: a 200-step, 7-camera, 1600 x 1200 session tracked in
// <= 60 s on the 2-core machine. The session is the simulated press of the tracking tests
// (tests/unit/tracking/track_support.h: 441 markers 3 mm apart, rendered probe, 2 grey levels of
// pixel noise), recorded once before the timing (set HC_BENCH_TRACK_SESSION=FILE to reuse one).
//  * BM_DecodeOnly: the baseline — read, decompress and decode every step frame of the session
//    (no detection): what merely looking at the frames costs.
//  * BM_TrackSession: the whole `hardcopy track` pipeline on the same session; counters give the
//    per-stage seconds (decode, detection, matching_triangulation, registration_filling), the
//    ratio to the baseline, the truth error, the filled markers' worst error and the probe pose
//    from the shaft markers (steps, fallbacks, tip error).
//
//   bench_tracking --benchmark_min_time=1
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>

#include "../unit/tracking/track_support.h"
#include "processing/tracking/session_tracking.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"

namespace {

namespace fs = std::filesystem;
using namespace hc;

constexpr int kSteps = 200;

struct Fixture {
  fs::path dir;
  fs::path session;
  RigCalibration calibration;
  TetMesh templ;
  double baseline_s = 0;
};

Fixture& fixture() {
  static Fixture f = [] {
    Fixture x;
    x.dir = fs::temp_directory_path() / ("hardcopy-bench-tracking-" + std::to_string(::getpid()));
    fs::create_directories(x.dir);
    const std::string rig = tracking::testing::hires_rig_yaml();
    if (const char* env = std::getenv("HC_BENCH_TRACK_SESSION")) {
      x.session = env;
    } else {
      const auto t0 = std::chrono::steady_clock::now();
      Result<fs::path> session = tracking::testing::record_session(
          x.dir, rig, tracking::testing::press_plan_yaml(kSteps, 20.0));
      if (!session.ok()) std::fprintf(stderr, "%s\n", session.status().to_string().c_str());
      x.session = session.ok() ? *session : fs::path();
      std::fprintf(stderr, "recorded %s in %.1f s\n", x.session.c_str(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    Result<RigCalibration> cal = tracking::testing::true_calibration(rig);
    if (cal.ok()) x.calibration = *cal;
    x.templ = tracking::testing::block_template();
    return x;
  }();
  return f;
}

void BM_DecodeOnly(benchmark::State& state) {
  Fixture& f = fixture();
  std::size_t frames = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    auto reader = recording::McapReader::open(f.session);
    if (!reader.ok()) {
      state.SkipWithError(reader.status().to_string().c_str());
      return;
    }
    recording::ReadOptions ro;
    for (const auto& c : f.calibration.cameras) ro.topics.push_back("/" + c.name + "/image");
    ro.order = recording::ReadOrder::kFile;
    frames = 0;
    Status s = reader->read_messages(ro, [&](const recording::MessageEvent& e) {
      auto im = recording::decode_raw_image(e.message.data);
      if (im.ok()) ++frames;
      benchmark::DoNotOptimize(im);
      return true;
    });
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
    f.baseline_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  state.counters["frames"] = static_cast<double>(frames);
}
BENCHMARK(BM_DecodeOnly)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

void BM_TrackSession(benchmark::State& state) {
  Fixture& f = fixture();
  tracking::TrackSummary sum;
  double total = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    auto det = tracking::read_session_detections(f.session, f.calibration);
    if (!det.ok()) {
      state.SkipWithError(det.status().to_string().c_str());
      return;
    }
    auto tr = tracking::track_detections(*det, f.calibration, f.templ);
    if (!tr.ok()) {
      state.SkipWithError(tr.status().to_string().c_str());
      return;
    }
    total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sum = tr->summary;
  }
  state.counters["steps"] = static_cast<double>(sum.steps);
  state.counters["markers"] = static_cast<double>(sum.markers);
  state.counters["decode_s"] = sum.times.decode_s;
  state.counters["detection_cpu_s"] = sum.times.detection_s;
  state.counters["frames_wall_s"] = sum.times.frames_s;
  state.counters["matching_triangulation_s"] = sum.times.matching_s;
  state.counters["registration_filling_s"] = sum.times.registration_s;
  state.counters["total_s"] = total;
  if (f.baseline_s > 0) state.counters["x_decode_baseline"] = total / f.baseline_s;
  state.counters["truth_rms_um"] = sum.truth_rms_error_m * 1e6;
  state.counters["truth_matched_fraction"] = sum.truth_matched_fraction;
  state.counters["filled"] = static_cast<double>(sum.filled);
  state.counters["filled_truth_max_um"] = sum.filled_truth_max_error_m * 1e6;
  state.counters["probe_from_markers"] = static_cast<double>(sum.probe_from_markers);
  state.counters["probe_fallbacks"] = static_cast<double>(sum.probe_fallbacks);
  state.counters["probe_tip_rms_um"] = sum.probe_truth_rms_error_m * 1e6;
  state.counters["probe_tip_max_um"] = sum.probe_truth_max_error_m * 1e6;
}
BENCHMARK(BM_TrackSession)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
