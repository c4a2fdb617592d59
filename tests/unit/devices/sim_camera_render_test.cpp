// Simulated cameras render on shared render threads (sim_camera.cpp), not inside read(): in
// simulated time the frames (pixels, stamps, counters, the read() that delivers them, the ground
// truth) are exactly those of the inline renderer (`render_thread: false`); in real time read()
// returns without waiting for pixels, frames keep their order, a buffer overrun counts lost, and
// stopping with frames in flight neither blocks nor loses count.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "rig_daemon/devices/trigger.h"
#include "sim_support.h"

namespace hc::devices {
namespace {

using testing::SimRig;

// Every frame one camera delivered, and after which poll (1 ms steps) it came.
struct Delivered {
  std::vector<Frame> frames;
  std::vector<int> poll_of_frame;
  DeviceStats stats;
};

struct Capture {
  std::map<std::string, Delivered> cameras;
  std::vector<sim::GroundTruth> truths;
};

// A session on a simulated rig: three hardware-triggered cameras (one with pixel noise, one with
// two frame buffers so that several frames due in one read overrun them), the probe pressing the
// specimen while a 50 Hz train fires, a dropout and a delay fault on cam1, then a calibration
// board for the last pulses. Polled like rigd's control loop: advance 1 ms, read every device.
Capture run_session(bool render_thread) {
  SimRig rig(11);
  Capture cap;
  rig.world->set_ground_truth_callback([&](const sim::GroundTruth& g) { cap.truths.push_back(g); });
  const std::string render = render_thread ? "true" : "false";
  auto arm = rig.make<Arm>("arm");
  auto trigger = rig.make<Trigger>("trigger", "{lines: [0]}");
  std::vector<std::unique_ptr<Camera>> cams;
  const std::string view = ", width: 320, height: 240, fx: 420, fy: 420, cx: 161.5, cy: 118.25";
  cams.push_back(rig.make<Camera>("cam0", "{trigger: hardware" + view +
                                              ", position_m: [0.2, 0, 0.25], look_at_m: [0, 0, "
                                              "0.055], pixel_noise: 3, render_thread: " +
                                              render + "}"));
  cams.push_back(rig.make<Camera>("cam1", "{trigger: hardware" + view +
                                              ", position_m: [0, -0.2, 0.25], look_at_m: [0, 0, "
                                              "0.055], render_buffers: 2, render_thread: " +
                                              render + "}"));
  cams.push_back(
      rig.make<Camera>("cam2", "{trigger: hardware" + view +
                                   ", position_m: [-0.14, -0.14, 0.3], look_at_m: [0, 0, "
                                   "0.05], render_thread: " +
                                   render + "}"));
  EXPECT_TRUE(arm->activate().ok());
  EXPECT_TRUE(trigger->activate().ok());
  for (auto& c : cams) EXPECT_TRUE(c->activate().ok());
  ArmCommand home;
  home.type = ArmCommand::Type::kHome;
  EXPECT_TRUE(arm->write(home).ok());
  rig.clock->advance_ns(10'000'000'000);
  ArmCommand press;
  press.type = ArmCommand::Type::kMoveTo;
  press.target = {0.002, -0.001, 0.05, 0.0};
  press.speed_m_s = 0.05;
  press.sequence = 2;
  EXPECT_TRUE(arm->write(press).ok());
  const std::int64_t t0 = rig.clock->now_ns();
  rig.world->inject(
      {sim::Fault::Kind::kDropout, "cam1", t0 + 100'000'000, t0 + 300'000'000, 0.5, 0.0});
  rig.world->inject(
      {sim::Fault::Kind::kDelay, "cam1", t0 + 350'000'000, t0 + 450'000'000, 1.0, 0.08});
  EXPECT_TRUE(trigger->start(PulseTrain{50.0, 0.001, 40}).ok());
  std::vector<TriggerEdge> edges;
  std::vector<Frame> frames;
  for (int poll = 0; poll < 1100; ++poll) {
    if (poll == 400) {  // the last pulses (from 600 ms on) show a board
      sim::BoardShow show;
      show.spec.cols = 6;
      show.spec.rows = 4;
      show.spec.square_m = 0.008;
      // Face up (the board's front is -z of its frame): 180 degrees about x.
      const Eigen::Matrix3d face_up = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
      show.poses = {sim::BoardPose{face_up, Eigen::Vector3d(-0.02, 0.01, 0.06)}};
      rig.world->show_board(show);
    }
    // Every 97 ms nobody reads for 40 ms: several frames are due in one read (cam1 overruns its
    // two buffers in real time; simulated time must not lose them).
    if (poll % 97 == 0) rig.clock->advance_ns(40'000'000);
    rig.clock->advance_ns(1'000'000);
    edges.clear();
    EXPECT_TRUE(trigger->read(edges, Duration(0)).ok());
    for (auto& c : cams) {
      frames.clear();
      Result<std::size_t> n = c->read(frames, Duration(0));
      EXPECT_TRUE(n.ok()) << n.status().to_string();
      Delivered& d = cap.cameras[c->name()];
      for (Frame& f : frames) {
        d.frames.push_back(std::move(f));
        d.poll_of_frame.push_back(poll);
      }
    }
  }
  for (auto& c : cams) {
    EXPECT_TRUE(c->deactivate().ok());
    cap.cameras[c->name()].stats = c->stats();
  }
  return cap;
}

TEST(SimCameraRender, SimulatedTimeThreadedFramesAreTheInlineFrames) {
  const Capture inline_run = run_session(false);
  const Capture threaded = run_session(true);
  ASSERT_EQ(inline_run.cameras.size(), 3u);
  for (const auto& [name, a] : inline_run.cameras) {
    SCOPED_TRACE(name);
    const Delivered& b = threaded.cameras.at(name);
    // 40 pulses, minus cam1's dropouts (probability 0.5 over 10 pulses: a seeded draw).
    if (name == "cam1") {
      EXPECT_GT(a.stats.lost, 0u);
      EXPECT_LT(a.stats.lost, 10u);
      EXPECT_GT(a.stats.late, 0u);  // 80 ms delay > late_after_s 50 ms
    } else {
      EXPECT_EQ(a.frames.size(), 40u);
    }
    EXPECT_EQ(a.frames.size() + a.stats.lost, 40u);
    ASSERT_EQ(a.frames.size(), b.frames.size());
    EXPECT_EQ(a.poll_of_frame, b.poll_of_frame);
    EXPECT_EQ(a.stats.received, b.stats.received);
    EXPECT_EQ(a.stats.lost, b.stats.lost);
    EXPECT_EQ(a.stats.late, b.stats.late);
    EXPECT_EQ(a.stats.last_host_ns, b.stats.last_host_ns);
    std::size_t with_scene = 0, with_board = 0;
    for (std::size_t i = 0; i < a.frames.size(); ++i) {
      const Frame& fa = a.frames[i];
      const Frame& fb = b.frames[i];
      EXPECT_EQ(fa.frame_index, fb.frame_index);
      EXPECT_EQ(fa.frame_id, fb.frame_id);
      EXPECT_EQ(fa.host_ns, fb.host_ns);
      EXPECT_EQ(fa.device_stamp_ns, fb.device_stamp_ns);
      EXPECT_EQ(fa.trigger_index, fb.trigger_index);
      EXPECT_TRUE(fb.valid());
      EXPECT_TRUE(fa.pixels == fb.pixels) << "frame " << i;
      // Not a blank scene: dots and the probe on the background (30), or the board's black
      // squares (25).
      const auto shown =
          std::count_if(fa.pixels.begin(), fa.pixels.end(), [](std::uint8_t p) { return p > 40; });
      const auto black =
          std::count_if(fa.pixels.begin(), fa.pixels.end(), [](std::uint8_t p) { return p < 28; });
      with_scene += shown > 1000;
      with_board += black > 300;
    }
    EXPECT_GT(with_scene, 20u);
    if (name != "cam0") {  // (cam0's pixel noise goes below 28)
      EXPECT_GT(with_board, 3u);
    }
  }
  // The same ground truth, once per exposure time, in the same order.
  ASSERT_EQ(inline_run.truths.size(), threaded.truths.size());
  EXPECT_EQ(inline_run.truths.size(), 40u);
  for (std::size_t i = 0; i < inline_run.truths.size(); ++i) {
    EXPECT_EQ(inline_run.truths[i].host_ns, threaded.truths[i].host_ns);
    EXPECT_EQ(inline_run.truths[i].markers_m, threaded.truths[i].markers_m);
  }
}

// A world on the host's monotonic clock with the arm at rest: every frame shows the same scene,
// so a frame's pixels depend only on its index (the pixel noise) and can be checked against the
// inline renderer in simulated time.
struct RealTimeRig {
  RealTimeRig() {
    sim::WorldOptions options;
    options.seed = 5;
    world = std::make_shared<sim::World>(options, monotonic_clock());
    EXPECT_TRUE(register_sim_backends(registry, world).ok());
  }
  std::unique_ptr<Camera> camera(const std::string& yaml) {
    DeviceContext ctx;
    ctx.name = "cam";
    ctx.backend = "sim";
    ctx.clock = world->clock_ptr();
    Result<std::unique_ptr<Camera>> made = registry.create<Camera>(ctx);
    EXPECT_TRUE(made.ok());
    if (!made.ok()) return nullptr;
    EXPECT_TRUE(configure_from_yaml(**made, yaml, "cam").ok());
    return std::move(made).value();
  }
  std::shared_ptr<sim::World> world;
  BackendRegistry registry;
};

// 1600 x 1200 with pixel noise: several ms of rendering per frame, far more than the 1 ms between
// frames at 1000 Hz, so the render threads fall behind and the frame buffers overrun.
constexpr const char* kFastBigCamera =
    "{trigger: free_run, frame_rate_hz: 1000, width: 1600, height: 1200, fx: 3500, fy: 3500,"
    " position_m: [0.2, 0, 0.25], look_at_m: [0, 0, 0.055], pixel_noise: 2, render_buffers: 3,"
    " render_thread: true}";

TEST(SimCameraRender, RealTimeReadsDoNotWaitForPixelsAndOverrunsCountLost) {
  using Clock = std::chrono::steady_clock;
  RealTimeRig rig;
  auto cam = rig.camera(kFastBigCamera);
  ASSERT_TRUE(cam->activate().ok());
  std::vector<Frame> got, frames;
  std::vector<double> read_ms;
  const auto until = Clock::now() + std::chrono::milliseconds(400);
  while (Clock::now() < until) {
    frames.clear();
    const auto t = Clock::now();
    ASSERT_TRUE(cam->read(frames, Duration(0)).ok());
    read_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
    for (Frame& f : frames) got.push_back(std::move(f));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  // Keep reading (with a timeout) until the frames in flight are in.
  for (int i = 0; i < 20; ++i) {
    frames.clear();
    ASSERT_TRUE(cam->read(frames, std::chrono::milliseconds(20)).ok());
    for (Frame& f : frames) got.push_back(std::move(f));
  }
  const DeviceStats during = cam->stats();
  ASSERT_TRUE(cam->deactivate().ok());
  const DeviceStats after = cam->stats();
  ASSERT_GT(got.size(), 3u);
  EXPECT_EQ(during.received, got.size());
  // About 400+ frames were due; a render takes milliseconds: most were lost to the overrun.
  EXPECT_GT(during.lost, got.size());
  // In order, and every gap in frame_index is a frame counted lost.
  std::uint64_t gaps = got.front().frame_index;
  for (std::size_t i = 1; i < got.size(); ++i) {
    ASSERT_GT(got[i].frame_index, got[i - 1].frame_index);
    ASSERT_GT(got[i].host_ns, got[i - 1].host_ns);
    gaps += got[i].frame_index - got[i - 1].frame_index - 1;
  }
  EXPECT_LE(gaps, during.lost);
  // Frames still in flight at deactivate() count lost too: everything emitted is accounted for.
  EXPECT_GE(after.received + after.lost, got.back().frame_index + 1);
  // read() hands the rendering over: the median call takes far less than one render (several ms
  // for 1600 x 1200 with noise; the inline path would take that in every read that emits).
  std::nth_element(read_ms.begin(), read_ms.begin() + read_ms.size() / 2, read_ms.end());
  EXPECT_LT(read_ms[read_ms.size() / 2], 1.0);

  // The pixels are those the inline renderer makes for the same frame index in simulated time
  // (a static scene; the noise is seeded by device name and frame index).
  SimRig sim(5);
  auto ref = sim.make<Camera>(
      "cam",
      std::string(kFastBigCamera).replace(std::string(kFastBigCamera).size() - 5, 5, "false}"));
  ASSERT_TRUE(ref->activate().ok());
  std::vector<Frame> ref_frames;
  const std::uint64_t last = std::min<std::uint64_t>(got[2].frame_index, 30);
  while (ref_frames.empty() || ref_frames.back().frame_index < last)
    ASSERT_TRUE(ref->read(ref_frames, std::chrono::milliseconds(5)).ok());
  for (std::size_t i = 0; i < 3; ++i) {
    if (got[i].frame_index > last) break;
    const Frame& r = ref_frames[got[i].frame_index];
    ASSERT_EQ(r.frame_index, got[i].frame_index);
    EXPECT_TRUE(r.pixels == got[i].pixels) << "frame " << got[i].frame_index;
  }
}

TEST(SimCameraRender, StoppingWithFramesInFlightNeitherBlocksNorLosesCount) {
  using Clock = std::chrono::steady_clock;
  RealTimeRig rig;
  auto cam = rig.camera(kFastBigCamera);
  for (int round = 0; round < 3; ++round) {
    SCOPED_TRACE(round);
    const DeviceStats before = cam->stats();
    ASSERT_TRUE(cam->activate().ok());
    std::vector<Frame> frames;
    // Frames are due 2 ms exposure + 28.5 ms readout after their start: about 10 by now.
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    ASSERT_TRUE(cam->read(frames, Duration(0)).ok());  // hands frames to the render threads
    const auto t = Clock::now();
    ASSERT_TRUE(cam->deactivate().ok());
    // No join on a render: deactivate() is quick even with 1600 x 1200 frames in flight.
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
    EXPECT_LT(ms, 50.0);
    const DeviceStats after = cam->stats();
    // Each frame due was delivered or counted lost.
    EXPECT_GE(after.received + after.lost - before.received - before.lost, 8u);
    EXPECT_EQ(after.received - before.received, frames.size());
  }
  // Destroyed with frames in flight (the render threads hold what they render).
  ASSERT_TRUE(cam->activate().ok());
  std::vector<Frame> frames;
  std::this_thread::sleep_for(std::chrono::milliseconds(40));
  ASSERT_TRUE(cam->read(frames, Duration(0)).ok());
  cam.reset();
  // A camera made after that gets working render threads again.
  auto again = rig.camera(kFastBigCamera);
  ASSERT_TRUE(again->activate().ok());
  frames.clear();
  for (int i = 0; i < 50 && frames.empty(); ++i)
    ASSERT_TRUE(again->read(frames, std::chrono::milliseconds(20)).ok());
  EXPECT_FALSE(frames.empty());
  EXPECT_TRUE(again->deactivate().ok());
}

TEST(SimCameraRender, FramesFinishedBeforeADisconnectAreDeliveredFirst) {
  RealTimeRig rig;
  auto cam = rig.camera(kFastBigCamera);
  ASSERT_TRUE(cam->activate().ok());
  std::vector<Frame> frames;
  std::this_thread::sleep_for(std::chrono::milliseconds(40));
  ASSERT_TRUE(cam->read(frames, Duration(0)).ok());  // hands frames to the render threads
  const std::size_t early = frames.size();
  // Time enough for the render threads to finish the three buffered frames (milliseconds each),
  // then the link goes down.
  std::this_thread::sleep_for(std::chrono::seconds(1));
  rig.world->inject({sim::Fault::Kind::kDisconnect, "cam", rig.world->clock().now_ns()});
  Result<std::size_t> n = cam->read(frames, Duration(0));
  ASSERT_TRUE(n.ok()) << n.status().to_string();  // the finished frames first
  EXPECT_EQ(*n + early, 3u);
  ASSERT_FALSE(frames.empty());
  EXPECT_EQ(frames.front().frame_index, 0u);
  EXPECT_TRUE(frames.back().valid());
  // Then the error; the device is in kError and lets go of its render stream.
  n = cam->read(frames, Duration(0));
  EXPECT_EQ(n.status().code(), StatusCode::kUnavailable);
  EXPECT_EQ(cam->state(), DeviceState::kError);
  (void)cam->deactivate();
  const DeviceStats st = cam->stats();
  EXPECT_EQ(st.received, 3u);
  EXPECT_EQ(st.errors, 1u);
}

}  // namespace
}  // namespace hc::devices
