// The "firmware" trigger and FSR backends on the firmware simulator (R2's host driver, the same
// API as the USB board): index agreement between edges and samples, the FSR reading the simulated
// world's force, and link faults surfacing as lost items.
#include <gtest/gtest.h>

#include <cmath>

#include "firmware_host/driver/shared_device.h"
#include "sim_support.h"

namespace hc::devices {
namespace {

using testing::SimRig;

struct Board {
  std::unique_ptr<Trigger> trigger;
  std::unique_ptr<Fsr> fsr;
};

Board open_board(SimRig& rig) {
  Board b;
  b.trigger = rig.make<Trigger>("trig", "{backend: firmware, device: sim, lines: [0, 2]}");
  b.fsr = rig.make<Fsr>("fsr", "{backend: firmware, device: sim, channel: 0}");
  EXPECT_TRUE(b.trigger && b.fsr);
  EXPECT_TRUE(b.trigger->activate().ok());
  EXPECT_TRUE(b.fsr->activate().ok());
  return b;
}

TEST(FirmwareBackends, EdgesAndSamplesShareTheirIndicesAcrossTrains) {
  SimRig rig;
  Board b = open_board(rig);
  PulseTrain train;
  train.rate_hz = 100.0;
  train.count = 5;
  std::vector<TriggerEdge> edges;
  std::vector<FsrSample> samples;
  for (int round = 0; round < 2; ++round) {
    Status started = b.trigger->start(train);
    ASSERT_TRUE(started.ok()) << started.to_string();
    for (int i = 0; i < 20 && edges.size() < 10u * (round + 1); ++i)
      ASSERT_TRUE(b.trigger->read(edges, std::chrono::milliseconds(10)).ok());
    for (int i = 0; i < 20 && samples.size() < 5u * (round + 1); ++i)
      ASSERT_TRUE(b.fsr->read(samples, std::chrono::milliseconds(10)).ok());
  }
  ASSERT_EQ(edges.size(), 20u);  // 2 trains x 5 pulses x 2 lines
  ASSERT_EQ(samples.size(), 10u);
  for (std::size_t i = 0; i < 10; ++i) {
    const TriggerEdge& e = edges[2 * i];
    EXPECT_EQ(e.index, i);
    EXPECT_EQ(e.line, 0u);
    EXPECT_EQ(edges[2 * i + 1].line, 2u);
    ASSERT_TRUE(samples[i].trigger_index);
    EXPECT_EQ(*samples[i].trigger_index, i);
    // The ADC is started at the edge; association error well under 1 ms.
    EXPECT_GE(samples[i].host_ns, e.host_ns);
    EXPECT_LT(samples[i].host_ns - e.host_ns, 1'000'000);
  }
  // 100 Hz within a train: 10 ms between edges, to the firmware's µs.
  EXPECT_NEAR(static_cast<double>(edges[2].host_ns - edges[0].host_ns), 10e6, 2e3);
  EXPECT_EQ(b.trigger->stats().lost, 0u);
  EXPECT_EQ(b.fsr->stats().received, 10u);
}

TEST(FirmwareBackends, FsrReadsTheWorldForceThroughItsPowerLaw) {
  SimRig rig;
  auto arm = rig.make<Arm>("arm");
  ASSERT_TRUE(arm->activate().ok());
  ArmCommand home;
  home.type = ArmCommand::Type::kHome;
  ASSERT_TRUE(arm->write(home).ok());
  rig.clock->advance_ns(10'000'000'000);
  ArmCommand press;
  press.target = {0.0, 0.0, 0.047, 0.0};  // 3 mm into the specimen
  ASSERT_TRUE(arm->write(press).ok());
  rig.clock->advance_ns(10'000'000'000);
  const double truth = rig.world->true_force_n(rig.clock->now_ns());
  ASSERT_GT(truth, 10.0);

  Board b = open_board(rig);
  PulseTrain train;
  train.rate_hz = 200.0;
  train.count = 20;
  ASSERT_TRUE(b.trigger->start(train).ok());
  std::vector<FsrSample> samples;
  for (int i = 0; i < 50 && samples.size() < 20; ++i)
    ASSERT_TRUE(b.fsr->read(samples, std::chrono::milliseconds(10)).ok());
  ASSERT_EQ(samples.size(), 20u);
  const FsrCalibration cal = b.fsr->calibration();
  for (const FsrSample& s : samples) {
    // raw = to_raw(F) rounded by a 12-bit ADC: the force is within one count's worth of it.
    const double per_count = cal.to_newtons(cal.to_raw(truth) + 1.0) - truth;
    EXPECT_NEAR(s.force_n, truth, 1.5 * per_count) << s.raw;
    EXPECT_NEAR(s.raw, cal.to_raw(truth), 1.0);
  }
}

TEST(FirmwareBackends, CorruptedLinkBytesSurfaceAsLostEdges) {
  SimRig rig;
  Board b = open_board(rig);
  Result<std::shared_ptr<fw::SharedFirmwareDevice>> board = [] {
    fw::OpenOptions o;
    o.device = "sim";
    return fw::SharedFirmwareDevice::acquire(o);  // the same board the backends hold
  }();
  ASSERT_TRUE(board.ok());
  PulseTrain train;
  train.rate_hz = 100.0;
  train.count = 40;
  ASSERT_TRUE(b.trigger->start(train).ok());
  std::vector<TriggerEdge> edges;
  ASSERT_TRUE(b.trigger->read(edges, std::chrono::milliseconds(55)).ok());
  // Flip bytes a little ahead in the device -> host stream: the frames holding them fail their
  // CRC and are dropped by the driver.
  (*board)->with_device([](fw::FirmwareDevice& d) {
    const std::uint64_t at = d.simulator()->in_bytes_sent();
    for (std::uint64_t k = 1; k <= 6; ++k) d.simulator()->corrupt_in_byte(at + 40 * k, 0x5A);
    return 0;
  });
  for (int i = 0; i < 60; ++i) (void)b.trigger->read(edges, std::chrono::milliseconds(10));
  const DeviceStats s = b.trigger->stats();
  EXPECT_EQ(b.trigger->state(), DeviceState::kActive);
  EXPECT_GT(s.lost, 0u);
  // Every pulse is either received (2 lines each) or counted lost, as long as the last one came.
  if (!edges.empty() && edges.back().index == 39) {
    EXPECT_EQ(s.received + s.lost, 80u);
  }
}

}  // namespace
}  // namespace hc::devices
