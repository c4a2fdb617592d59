// SharedFirmwareDevice: one board, a trigger consumer and an FSR consumer on two threads.
#include <gtest/gtest.h>

#include <thread>

#include "firmware_host/core/firmware.h"
#include "firmware_host/driver/shared_device.h"

namespace hc::fw {
namespace {

using namespace std::chrono_literals;

TEST(SharedFirmwareDevice, AcquireSharesOneBoardPerDeviceString) {
  OpenOptions opts;  // "sim"
  auto a = SharedFirmwareDevice::acquire(opts);
  auto b = SharedFirmwareDevice::acquire(opts);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->get(), b->get());
  auto c = SharedFirmwareDevice::create(opts);
  ASSERT_TRUE(c.ok());
  EXPECT_NE(a->get(), c->get());
  *a = nullptr;
  *b = nullptr;
  // Released: the next acquire opens a fresh board (whose sequencer is idle again).
  auto d = SharedFirmwareDevice::acquire(opts);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(
      (*d)->with_device([](FirmwareDevice& dev) { return dev.simulator()->firmware().state(); }),
      SequencerState::kIdle);
  OpenOptions bad;
  bad.device = "usb:nope";
  EXPECT_EQ(SharedFirmwareDevice::acquire(bad).status().code(), StatusCode::kInvalidArgument);
}

TEST(SharedFirmwareDevice, TriggerAndFsrThreadsEachGetTheirWholeStream) {
  OpenOptions opts;
  opts.sim.adc_source = [](std::uint8_t, std::uint64_t t_us) { return 1e-6 * (t_us % 3'000'000); };
  auto opened = SharedFirmwareDevice::create(opts);
  ASSERT_TRUE(opened.ok());
  std::shared_ptr<SharedFirmwareDevice> board = *opened;
  TriggerConfig cfg;
  cfg.period_us = 1'000;
  cfg.pulse_width_us = 100;
  cfg.adc_channels_mask = 0b0001;
  cfg.count = 300;
  ASSERT_TRUE(board->configure_trigger(cfg).ok());
  ASSERT_TRUE(board->start().ok());

  std::vector<TriggerEdgeEvent> edges;
  std::vector<AdcSampleEvent> samples;
  std::thread trigger([&] {
    for (int i = 0; i < 2'000 && edges.size() < 300; ++i)
      ASSERT_TRUE(board->read_edges(edges, 5ms).ok());
  });
  std::thread fsr([&] {
    for (int i = 0; i < 2'000 && samples.size() < 300; ++i)
      ASSERT_TRUE(board->read_samples(samples, 5ms).ok());
  });
  trigger.join();
  fsr.join();
  ASSERT_EQ(edges.size(), 300u);
  ASSERT_EQ(samples.size(), 300u);
  for (std::size_t k = 0; k < 300; ++k) {
    EXPECT_EQ(edges[k].edge_index, k);
    EXPECT_EQ(samples[k].edge_index, k);
    EXPECT_EQ(samples[k].device_time_us, edges[k].device_time_us);
    EXPECT_EQ(edges[k].device_time_us - edges[0].device_time_us, 1'000 * k);
  }
  EXPECT_EQ(board->queue_overflows(), 0u);
  EXPECT_TRUE(board->take_errors().empty());
  EXPECT_EQ(board->link_stats().frames_lost, 0u);
}

}  // namespace
}  // namespace hc::fw
