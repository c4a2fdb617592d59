// The simulated world through the sim backends: arm motion over simulated time, forces reported by
// the virtual sensors against the specimen's true force, trigger association, ground truth, faults.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>

#include "sim_support.h"

namespace hc::devices {
namespace {

using testing::SimRig;

void home_and_move(SimRig& rig, Arm& arm, const ArmPose& target) {
  ArmCommand home;
  home.type = ArmCommand::Type::kHome;
  ASSERT_TRUE(arm.write(home).ok());
  rig.clock->advance_ns(10'000'000'000);
  ArmCommand move;
  move.type = ArmCommand::Type::kMoveTo;
  move.target = target;
  move.sequence = 2;
  ASSERT_TRUE(arm.write(move).ok());
}

TEST(SimWorld, ArmMovesAtItsSpeedAndReportsMotion) {
  SimRig rig;
  auto arm = rig.make<Arm>("arm");
  ASSERT_TRUE(arm->activate().ok());
  ArmCommand move;
  move.type = ArmCommand::Type::kMoveTo;
  move.target = {0.0, 0.0, 0.1, 0.0};
  // Not homed yet: refused, but not a device error.
  EXPECT_EQ(arm->write(move).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(arm->state(), DeviceState::kActive);
  move.target = {0.0, 0.0, 0.5, 0.0};
  EXPECT_EQ(arm->write(move).code(), StatusCode::kInvalidArgument);  // outside the workspace

  home_and_move(*&rig, *arm, {0.0, 0.0, 0.05, 0.0});  // home z = 0.15: 0.1 m at 0.02 m/s = 5 s
  rig.clock->advance_ns(2'500'000'000);
  Result<ArmState> s = arm->read();
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->motion, ArmMotion::kMoving);
  EXPECT_NEAR(s->pose.z_m, 0.10, 1e-9);  // halfway
  EXPECT_EQ(s->command_sequence, 2u);
  EXPECT_TRUE(s->homed);
  rig.clock->advance_ns(2'600'000'000);
  s = arm->read();
  EXPECT_EQ(s->motion, ArmMotion::kHolding);
  EXPECT_NEAR(s->pose.z_m, 0.05, 1e-12);

  // stop() freezes the arm where it is, from any state.
  move.target = {0.0, 0.0, 0.15, 0.0};
  ASSERT_TRUE(arm->write(move).ok());
  rig.clock->advance_ns(1'000'000'000);
  ASSERT_TRUE(arm->stop().ok());
  rig.clock->advance_ns(1'000'000'000);
  s = arm->read();
  EXPECT_EQ(s->motion, ArmMotion::kStopped);
  EXPECT_NEAR(s->pose.z_m, 0.07, 1e-9);
}

TEST(SimWorld, ForceSensorReportsTheSpecimenForceWithNoiseAndBias) {
  sim::WorldOptions options;
  SimRig rig(3, options);
  auto arm = rig.make<Arm>("arm");
  auto ft = rig.make<ForceTorque>("ft", "{rate_hz: 1000, drift_n_per_s: 0}");
  ASSERT_TRUE(arm->activate().ok());
  // Indent the specimen (top at z = 0.05) by 2 mm.
  home_and_move(rig, *arm, {0.0, 0.0, 0.048, 0.0});
  rig.clock->advance_ns(10'000'000'000);
  ASSERT_TRUE(ft->activate().ok());
  std::vector<WrenchSample> samples;
  while (samples.size() < 2000) ASSERT_TRUE(ft->read(samples, std::chrono::milliseconds(50)).ok());
  const double truth = rig.world->true_force_n(rig.clock->now_ns());
  // Hertz with stiffening (defaults E = 1 MPa, nu = 0.45, R = 5 mm, s = 0.5) at d = 2 mm:
  // 4/3 * 1.2539185e6 * sqrt(0.005) * 0.002^1.5 * (1 + 0.5 * 0.4) = 12.68876 N.
  EXPECT_NEAR(truth, 12.68876, 1e-4);
  double mean = 0.0, var = 0.0;
  for (const auto& s : samples) mean += s.force_n[2];
  mean /= samples.size();
  for (const auto& s : samples) var += (s.force_n[2] - mean) * (s.force_n[2] - mean);
  const double sd = std::sqrt(var / (samples.size() - 1));
  // Noise sd 1/24 N (the Nano25's resolution): the mean of 2000 samples is within 4 sd / sqrt(n).
  EXPECT_NEAR(mean, truth, 4.0 * (1.0 / 24.0) / std::sqrt(2000.0));
  EXPECT_NEAR(sd, 1.0 / 24.0, 0.1 / 24.0);
  // Counts are the SI value times counts per unit.
  EXPECT_NEAR(samples[0].counts[2] / 1e6, samples[0].force_n[2], 1e-6);
  // Tare: afterwards the reading is about zero.
  ASSERT_TRUE(ft->bias().ok());
  samples.clear();
  while (samples.size() < 500) ASSERT_TRUE(ft->read(samples, std::chrono::milliseconds(50)).ok());
  mean = 0.0;
  for (const auto& s : samples) mean += s.force_n[2];
  EXPECT_NEAR(mean / samples.size(), 0.0, 0.2);
}

TEST(SimWorld, HardwareTriggeredCamerasAndFsrFollowTheTriggerEdges) {
  SimRig rig;
  auto trigger = rig.make<Trigger>("trig", "{lines: [0]}");
  std::vector<std::unique_ptr<Camera>> cams;
  for (int i = 0; i < 3; ++i)
    cams.push_back(rig.make<Camera>("cam" + std::to_string(i),
                                    "{trigger: hardware, width: 160, height: 120, fx: 200}"));
  auto fsr = rig.make<Fsr>("fsr", "{sampling: triggered}");
  std::vector<sim::GroundTruth> truths;
  rig.world->set_ground_truth_callback([&](const sim::GroundTruth& g) { truths.push_back(g); });
  ASSERT_TRUE(trigger->activate().ok());
  for (auto& c : cams) ASSERT_TRUE(c->activate().ok());
  ASSERT_TRUE(fsr->activate().ok());
  PulseTrain train;
  train.rate_hz = 15.0;
  train.count = 10;
  ASSERT_TRUE(trigger->start(train).ok());
  EXPECT_TRUE(trigger->running());
  EXPECT_EQ(trigger->fire().code(), StatusCode::kFailedPrecondition);  // a train is running
  rig.clock->advance_ns(1'000'000'000);
  EXPECT_FALSE(trigger->running());

  std::vector<TriggerEdge> edges;
  ASSERT_TRUE(trigger->read(edges, Duration(0)).ok());
  ASSERT_EQ(edges.size(), 10u);
  std::vector<FsrSample> samples;
  ASSERT_TRUE(fsr->read(samples, Duration(0)).ok());
  ASSERT_EQ(samples.size(), 10u);
  for (std::size_t i = 0; i < 10; ++i) {
    EXPECT_EQ(edges[i].index, i);
    // 15 Hz: 66.667 ms apart (rounded to whole ns).
    if (i) {
      EXPECT_NEAR(edges[i].host_ns - edges[i - 1].host_ns, 66'666'667, 1);
    }
    ASSERT_TRUE(samples[i].trigger_index);
    EXPECT_EQ(*samples[i].trigger_index, i);
    // Sampled 20 us after the edge (ADC conversion): association error well under 1 ms.
    EXPECT_EQ(samples[i].host_ns - edges[i].host_ns, 20'000);
  }
  for (auto& c : cams) {
    std::vector<Frame> frames;
    ASSERT_TRUE(c->read(frames, Duration(0)).ok());
    ASSERT_EQ(frames.size(), 10u);
    for (std::size_t i = 0; i < 10; ++i) {
      EXPECT_EQ(*frames[i].trigger_index, i);
      EXPECT_EQ(frames[i].frame_id, (65400u + i) & 0xFFFFu);
      EXPECT_TRUE(frames[i].valid());
      // Ready after exposure (2 ms) + readout (120 lines x 20.52 us + 3873.2 us = 6335.6 us).
      EXPECT_EQ(frames[i].host_ns - edges[i].host_ns, 2'000'000 + 6'335'600);
    }
  }
  // Ground truth once per exposure, not once per camera.
  ASSERT_EQ(truths.size(), 10u);
  EXPECT_EQ(*truths[3].trigger_index, 3u);
  EXPECT_EQ(truths[3].markers_m.size(), 441u);
}

TEST(SimWorld, FramesShowTheMarkersAndTheirDeformation) {
  sim::WorldOptions options;
  options.probe.visible = false;  // the dots alone (the probe is tested in sim_scene_test.cpp)
  SimRig rig(7, options);
  auto arm = rig.make<Arm>("arm");
  // Straight down from 0.3 m above the specimen centre: the 3 mm grid spans 60 mm -> 200 px.
  auto cam = rig.make<Camera>("cam",
                              "{trigger: software, width: 400, height: 400, fx: 1000,"
                              " position_m: [0, 0, 0.35], look_at_m: [0, 0, 0.05]}");
  ASSERT_TRUE(arm->activate().ok());
  ASSERT_TRUE(cam->activate().ok());
  EXPECT_EQ(cam->camera_info().trigger_mode, TriggerMode::kSoftware);
  auto grab = [&] {
    EXPECT_TRUE(cam->software_trigger().ok());
    std::vector<Frame> frames;
    EXPECT_TRUE(cam->read(frames, std::chrono::milliseconds(100)).ok());
    EXPECT_EQ(frames.size(), 1u);
    return frames.empty() ? Frame{} : frames[0];
  };
  const Frame rest = grab();
  std::size_t bright = 0;
  for (std::uint8_t p : rest.pixels) bright += p > 125;
  // 441 dots of radius 0.6 mm at 0.3 m with f = 1000 px: r = 2 px, area 4 pi px^2 each.
  EXPECT_NEAR(static_cast<double>(bright), 441 * 4 * std::numbers::pi,
              0.15 * 441 * 4 * std::numbers::pi);
  home_and_move(rig, *arm, {0.0, 0.0, 0.046, 0.0});
  rig.clock->advance_ns(10'000'000'000);
  const Frame pressed = grab();
  std::size_t changed = 0;
  for (std::size_t i = 0; i < rest.pixels.size(); ++i)
    changed += rest.pixels[i] != pressed.pixels[i];
  EXPECT_GT(changed, 100u);  // dots near the probe moved
}

TEST(SimWorld, SpikesAndDelaysSurface) {
  SimRig rig;
  auto ft = rig.make<ForceTorque>("ft", "{rate_hz: 1000, noise_n: 0, drift_n_per_s: 0}");
  ASSERT_TRUE(ft->activate().ok());
  const std::int64_t t = rig.clock->now_ns();
  rig.world->inject({sim::Fault::Kind::kSpike, "ft", t + 10'000'000, t + 12'000'000, 1.0, 80.0});
  rig.world->inject({sim::Fault::Kind::kDelay, "ft", t + 50'000'000, t + 60'000'000, 1.0, 0.02});
  std::vector<WrenchSample> samples;
  while (rig.clock->now_ns() < t + 200'000'000)
    ASSERT_TRUE(ft->read(samples, std::chrono::milliseconds(5)).ok());
  int spikes = 0;
  for (const auto& s : samples) spikes += s.force_n[2] > 79.0;
  EXPECT_EQ(spikes, 2);              // samples at 10 and 11 ms
  EXPECT_EQ(ft->stats().late, 10u);  // 20 ms late > the 5 ms bound
  EXPECT_EQ(ft->stats().lost, 0u);
}

TEST(SimWorld, StalledArmFreezesAndReportsAFault) {
  SimRig rig;
  auto arm = rig.make<Arm>("arm");
  ASSERT_TRUE(arm->activate().ok());
  home_and_move(rig, *arm, {0.0, 0.0, 0.05, 0.0});
  const std::int64_t t = rig.clock->now_ns();
  rig.world->inject(
      {sim::Fault::Kind::kStall, "arm", t + 1'000'000'000, t + 3'000'000'000, 1.0, 0.0});
  rig.clock->advance_ns(2'000'000'000);
  Result<ArmState> s = arm->read();
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->motion, ArmMotion::kFault);
  EXPECT_EQ(s->fault_code, 2u);
  EXPECT_NEAR(s->pose.z_m, 0.15 - 0.02, 1e-9);  // frozen after 1 s at 0.02 m/s
}

TEST(Registry, UnknownBackendsDuplicatesAndMissingWorldAreErrors) {
  SimRig rig;
  DeviceContext ctx = rig.context("cam0", "gige");
  Result<std::unique_ptr<Camera>> made = rig.registry.create<Camera>(ctx);
  ASSERT_FALSE(made.ok());
  EXPECT_EQ(made.status().code(), StatusCode::kNotFound);
  EXPECT_NE(made.status().message().find("known: sim"), std::string::npos)
      << made.status().message();
  EXPECT_EQ(register_sim_backends(rig.registry, rig.world).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(rig.registry.backends(DeviceKind::kArm), (std::vector<std::string>{"sim"}));
  EXPECT_EQ(rig.registry.backends(DeviceKind::kFsr), (std::vector<std::string>{"firmware", "sim"}));
  BackendRegistry empty;
  EXPECT_EQ(register_sim_backends(empty, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(device_kind_from_string("force_torque"), DeviceKind::kForceTorque);
  EXPECT_FALSE(device_kind_from_string("laser"));
}

TEST(SimWorld, ConfigErrorsNameTheKey) {
  SimRig rig;
  auto made = rig.registry.create<ForceTorque>(rig.context("ft"));
  ASSERT_TRUE(made.ok());
  Status s = configure_from_yaml(**made, "{rate_hz: 9000}", "rig.yaml");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("rate_hz"), std::string::npos) << s.message();
  EXPECT_EQ((*made)->state(), DeviceState::kUnconfigured);
  sim::WorldOptions w;
  Result<Config> config = parse_config("{seed: 4, specimen: {poisson_ratio: 0.7}}", "w.yaml");
  ASSERT_TRUE(config.ok());
  s = read_config(*config, w);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("poisson_ratio"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace hc::devices
