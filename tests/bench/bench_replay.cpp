// Rig daemon numbers the issue asks for, on the simulated rig (embedded default, seeded):
//  * BM_ReplayForceChannel: replaying a recorded session's force-torque channel through the
//    "replay" ForceTorque backend on a simulated clock (as fast as the CPU allows); counter
//    x_realtime = recorded seconds replayed per wall second (target >= 10).
//  * BM_AssociationError: a whole automated (and hand-held) capture; counters are the largest and
//    mean |F/T sample time - trigger edge time| over every edge (target < 1 ms) and the FSR's.
//  * BM_OverForceStop: a 100 N spike during a press; counter stop_latency_us = time from the F/T
//    sample that crossed the limit to the arm stop command (target <= one control cycle, 1 ms).
//
//   bench_replay --benchmark_min_time=1
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/replay/replay.h"

namespace {

namespace fs = std::filesystem;
using hc::Json;

fs::path scratch() {
  static const fs::path dir = [] {
    fs::path d =
        fs::temp_directory_path() / ("hardcopy-bench-replay-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

std::unique_ptr<hc::rig::Daemon> make_daemon(const std::string& sub) {
  hc::Result<hc::rig::RigConfig> cfg = hc::rig::embedded_default_rig_config();
  if (!cfg.ok()) return nullptr;
  cfg->sessions_dir = scratch() / sub;
  hc::rig::Daemon::Options o;
  o.config = *cfg;
  o.clock = std::make_shared<hc::devices::SimulatedClock>(1'000'000'000);
  hc::Result<std::unique_ptr<hc::rig::Daemon>> d = hc::rig::Daemon::create(o);
  return d.ok() ? std::move(d).value() : nullptr;
}

Json run(hc::rig::Daemon& d, const std::string& plan_file) {
  hc::Result<hc::rig::Plan> plan =
      hc::rig::load_plan(fs::path(HARDCOPY_SOURCE_DIR) / "rig_daemon/examples" / plan_file);
  if (!plan.ok() || !d.start(*plan).ok()) return Json();
  d.wait_idle(600000);
  return d.last_summary();
}

// One automated session recorded once per process.
const Json& automated_summary() {
  static const Json summary = [] {
    auto d = make_daemon("automated");
    return d ? run(*d, "automated_block.yaml") : Json();
  }();
  return summary;
}

void BM_ReplayForceChannel(benchmark::State& state) {
  const Json& s = automated_summary();
  if (!s.contains("session")) {
    state.SkipWithError("could not record the automated session");
    return;
  }
  const fs::path path = s["session"].get<std::string>();
  double recorded_s = 0;
  std::size_t samples = 0;
  for (auto _ : state) {
    auto clock = std::make_shared<hc::devices::SimulatedClock>();
    auto session = hc::devices::ReplaySession::open(path);
    if (!session.ok()) {
      state.SkipWithError(session.status().to_string().c_str());
      return;
    }
    hc::devices::BackendRegistry registry;
    (void)hc::devices::register_replay_backends(registry, *session);
    hc::devices::DeviceContext ctx;
    ctx.name = "ft";
    ctx.backend = "replay";
    ctx.clock = clock;
    auto ft = registry.create<hc::devices::ForceTorque>(ctx);
    if (!ft.ok() || !hc::devices::configure_from_yaml(**ft, "").ok() || !(*ft)->activate().ok()) {
      state.SkipWithError("replay F/T would not start");
      return;
    }
    const hc::devices::ReplaySession::Stream* stream =
        (*session)->find("ft", hc::devices::DeviceKind::kForceTorque);
    const std::int64_t end = (*session)->due_clock_ns((*session)->end_ns());
    std::vector<hc::devices::WrenchSample> buf;
    std::size_t n = 0;
    while (true) {
      buf.clear();
      hc::Result<std::size_t> got = (*ft)->read(buf, std::chrono::milliseconds(100));
      if (!got.ok()) break;
      n += *got;
      if (*got == 0 && clock->now_ns() > end) break;
    }
    benchmark::DoNotOptimize(n);
    samples = n;
    recorded_s = stream ? double((*session)->end_ns() - (*session)->start_ns()) * 1e-9 : 0.0;
    if (stream && n != stream->messages) state.SkipWithError("replay lost samples");
  }
  state.counters["samples"] = double(samples);
  state.counters["recorded_s"] = recorded_s;
  // Recorded seconds per wall second: the replay speed-up over real time.
  state.counters["x_realtime"] =
      benchmark::Counter(recorded_s, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ReplayForceChannel)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_AssociationError(benchmark::State& state) {
  Json automated, hand_held;
  for (auto _ : state) {
    automated = automated_summary();
    auto d = make_daemon("hand_held");
    hand_held = d ? run(*d, "hand_held_face.yaml") : Json();
  }
  if (!automated.contains("association") || !hand_held.contains("association")) {
    state.SkipWithError("sessions failed");
    return;
  }
  const Json& a = automated["association"];
  state.counters["ft_max_err_us"] = a["max_abs_ft_error_ns"].get<double>() * 1e-3;
  state.counters["ft_mean_err_us"] = a["mean_abs_ft_error_ns"].get<double>() * 1e-3;
  state.counters["edges"] = a["edges"].get<double>();
  state.counters["edges_complete"] = a["edges_complete"].get<double>();
  state.counters["frames_assoc_pct"] = a["frame_association"].get<double>() * 100.0;
  const Json& h = hand_held["association"];
  state.counters["fsr_max_err_us"] = h["max_abs_fsr_error_ns"].get<double>() * 1e-3;
  state.counters["hh_edges_complete"] = h["edges_complete"].get<double>();
}
BENCHMARK(BM_AssociationError)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_OverForceStop(benchmark::State& state) {
  Json trip;
  for (auto _ : state) {
    auto d = make_daemon("overforce");
    if (!d) break;
    d->rig().world()->inject(hc::devices::sim::Fault{hc::devices::sim::Fault::Kind::kSpike, "ft",
                                                     3'200'000'000, INT64_MAX, 1.0, 100.0});
    Json s = run(*d, "automated_block.yaml");
    if (s.contains("trip")) trip = s["trip"];
  }
  if (!trip.contains("latency_ns")) {
    state.SkipWithError("no over-force trip");
    return;
  }
  state.counters["stop_latency_us"] = trip["latency_ns"].get<double>() * 1e-3;
  state.counters["control_period_us"] = 1000.0;
  state.counters["force_n"] = trip["force_n"].get<double>();
}
BENCHMARK(BM_OverForceStop)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  fs::remove_all(scratch(), ec);
  return 0;
}
