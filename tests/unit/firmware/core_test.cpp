// Portable firmware core against a scripted HAL: exact edge timing, sample-to-edge association,
// command validation, ring-buffer overflow accounting, late edges, ADC timeouts, heartbeats.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "fake_hal.h"
#include "firmware_host/core/firmware.h"
#include "firmware_host/core/spsc_ring.h"

namespace hc::fw {
namespace {

using testing::FakeHal;
using testing::GpioWrite;
using testing::received;
using testing::run_until;

class CoreTest : public ::testing::Test {
 protected:
  FakeHal hal;
  FirmwareInfo info;
  Firmware fw{hal, info};
  StreamDecoder host;
  std::uint16_t seq = 100;

  std::vector<Message> command(Message m) {
    m.seq = seq++;
    hal.send(m);
    run_until(hal, fw, hal.now + 200);
    return received(hal, host);
  }
  // The single Ack/Nack answering the last command (skipping heartbeats/events).
  Message answer(const std::vector<Message>& msgs) {
    for (const Message& m : msgs)
      if (m.type == MessageType::kAck || m.type == MessageType::kNack ||
          m.type == MessageType::kHelloReply)
        return m;
    ADD_FAILURE() << "no answer";
    return {};
  }
  Message configure_msg(std::uint32_t period, std::uint32_t width, std::uint8_t lines,
                        std::uint8_t adc, std::uint32_t count, std::uint16_t hb_ms = 0) {
    Message m = make_message(MessageType::kConfigureTrigger, 0);
    m.configure = {period, width, lines, adc, count, hb_ms};
    return m;
  }
  void hello() {
    const Message r = answer(command(make_message(MessageType::kHello, 0)));
    ASSERT_EQ(r.type, MessageType::kHelloReply);
  }
};

TEST_F(CoreTest, HelloReportsVersionAndCapabilities) {
  const Message r = answer(command(make_message(MessageType::kHello, 0)));
  ASSERT_EQ(r.type, MessageType::kHelloReply);
  EXPECT_EQ(r.hello_reply.protocol_version, kProtocolVersion);
  EXPECT_EQ(r.hello_reply.num_trigger_lines, 4);
  EXPECT_EQ(r.hello_reply.num_adc_channels, 4);
  EXPECT_EQ(r.hello_reply.adc_bits, 12);
  EXPECT_EQ(r.hello_reply.event_capacity, kEventCapacity);

  Message bad = make_message(MessageType::kHello, 0);
  bad.hello.protocol_version = kProtocolVersion + 1;
  const Message n = answer(command(bad));
  ASSERT_EQ(n.type, MessageType::kNack);
  EXPECT_EQ(n.nack.reason, NackReason::kBadVersion);
  EXPECT_EQ(n.nack.acked_seq, seq - 1);
}

TEST_F(CoreTest, InvalidConfigurationsAreNackedWithTheField) {
  hello();
  struct Case {
    Message msg;
    ConfigField field;
  };
  const Case cases[] = {
      {configure_msg(99, 10, 1, 1, 0), ConfigField::kPeriod},
      {configure_msg(1000, 0, 1, 1, 0), ConfigField::kPulseWidth},
      {configure_msg(1000, 1000, 1, 1, 0), ConfigField::kPulseWidth},
      {configure_msg(1000, 10, 0, 1, 0), ConfigField::kLinesMask},
      {configure_msg(1000, 10, 0x10, 1, 0), ConfigField::kLinesMask},  // 4 lines: bits 0-3
      {configure_msg(1000, 10, 1, 0x20, 0), ConfigField::kAdcChannelsMask},
      {configure_msg(1000, 10, 1, 1, 0, 9), ConfigField::kHeartbeatPeriod},
  };
  for (const Case& c : cases) {
    const Message n = answer(command(c.msg));
    ASSERT_EQ(n.type, MessageType::kNack);
    EXPECT_EQ(n.nack.reason, NackReason::kInvalidConfig);
    EXPECT_EQ(n.nack.detail, static_cast<std::uint8_t>(c.field));
    EXPECT_EQ(n.nack.acked_type, MessageType::kConfigureTrigger);
  }
  EXPECT_EQ(fw.state(), SequencerState::kIdle);
  // Boundary values are accepted: 100 µs period, width = period - 1, all lines, no ADC.
  EXPECT_EQ(answer(command(configure_msg(100, 99, 0x0F, 0, 0, 10))).type, MessageType::kAck);
  EXPECT_EQ(fw.state(), SequencerState::kConfigured);
}

TEST_F(CoreTest, StartNeedsConfigurationAndDeviceMessagesAreRefused) {
  hello();
  Message n = answer(command(make_message(MessageType::kStart, 0)));
  ASSERT_EQ(n.type, MessageType::kNack);
  EXPECT_EQ(n.nack.reason, NackReason::kNotConfigured);
  n = answer(command(make_message(MessageType::kHeartbeat, 0)));
  ASSERT_EQ(n.type, MessageType::kNack);
  EXPECT_EQ(n.nack.reason, NackReason::kUnexpected);
}

TEST_F(CoreTest, PulseTrainHasExactEdgesAndOneSamplePerChannelPerEdge) {
  hello();
  ASSERT_EQ(answer(command(configure_msg(1000, 200, 0b0101, 0b0011, 5))).type, MessageType::kAck);
  const std::vector<Message> started = command(make_message(MessageType::kStart, 0));
  // Start handled at the first main-loop pass after the command arrived.
  ASSERT_EQ(answer(started).type, MessageType::kAck);
  // The Ack leaves before the first edge (kMinStartDelayUs).
  ASSERT_FALSE(started.empty());
  EXPECT_EQ(started[0].type, MessageType::kAck);
  run_until(hal, fw, hal.now + 10'000);
  std::vector<Message> msgs = started;
  const std::vector<Message> more = received(hal, host);
  msgs.insert(msgs.end(), more.begin(), more.end());

  // GPIO: 5 rises at t0 + k * 1000 µs, falls 200 µs later, always on lines 0 and 2 only.
  ASSERT_EQ(hal.gpio.size(), 10u);
  const std::uint64_t t0 = hal.gpio[0].t_us;
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(hal.gpio[2 * k].t_us, t0 + 1000 * k);
    EXPECT_TRUE(hal.gpio[2 * k].high);
    EXPECT_EQ(hal.gpio[2 * k + 1].t_us, t0 + 1000 * k + 200);
    EXPECT_FALSE(hal.gpio[2 * k + 1].high);
    EXPECT_EQ(hal.gpio[2 * k].mask, 0b0101);
  }
  EXPECT_EQ(hal.lines, 0);
  EXPECT_EQ(fw.state(), SequencerState::kDone);

  std::vector<Message> edges, samples;
  for (const Message& m : msgs) {
    if (m.type == MessageType::kTriggerEdge) edges.push_back(m);
    if (m.type == MessageType::kAdcSample) samples.push_back(m);
  }
  ASSERT_EQ(edges.size(), 5u);
  ASSERT_EQ(samples.size(), 10u);
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(edges[k].edge.edge_index, k);
    EXPECT_EQ(edges[k].edge.timestamp_us, t0 + 1000 * k);
    EXPECT_EQ(edges[k].edge.lines_mask, 0b0101);
    EXPECT_EQ(edges[k].edge.lateness_us, 0);
    for (std::uint8_t ch = 0; ch < 2; ++ch) {
      const Message& s = samples[2 * k + ch];
      EXPECT_EQ(s.sample.edge_index, k);
      EXPECT_EQ(s.sample.channel, ch);
      // Channel 0 converts at the edge; channel 1 right after channel 0's 3 µs conversion.
      const std::uint64_t t = t0 + 1000 * k + 3 * ch;
      EXPECT_EQ(s.sample.timestamp_us, t);
      EXPECT_EQ(s.sample.raw, hal.adc_source(ch, t));
    }
  }
  // Device sequence numbers are consecutive (no frame lost).
  for (std::size_t i = 1; i < msgs.size(); ++i)
    EXPECT_EQ(static_cast<std::uint16_t>(msgs[i].seq),
              static_cast<std::uint16_t>(msgs[i - 1].seq + 1));
  EXPECT_EQ(hal.critical_depth, 0);
}

TEST_F(CoreTest, StopEndsAContinuousTrainWithLinesLow) {
  hello();
  ASSERT_EQ(answer(command(configure_msg(500, 100, 0b0001, 0, 0))).type, MessageType::kAck);
  ASSERT_EQ(answer(command(make_message(MessageType::kStart, 0))).type, MessageType::kAck);
  // Reconfiguring while running is refused.
  const Message busy = answer(command(configure_msg(1000, 100, 1, 0, 0)));
  ASSERT_EQ(busy.type, MessageType::kNack);
  EXPECT_EQ(busy.nack.reason, NackReason::kBusy);
  run_until(hal, fw, hal.now + 5'030);  // mid-pulse
  ASSERT_EQ(answer(command(make_message(MessageType::kStop, 0))).type, MessageType::kAck);
  const std::size_t writes = hal.gpio.size();
  EXPECT_EQ(hal.lines, 0);
  EXPECT_FALSE(hal.armed.has_value());
  run_until(hal, fw, hal.now + 5'000);
  EXPECT_EQ(hal.gpio.size(), writes);
  EXPECT_EQ(fw.state(), SequencerState::kConfigured);
  EXPECT_GE(fw.edges_emitted(), 10u);
  EXPECT_GE(hal.max_critical_depth, 1);
  EXPECT_EQ(hal.critical_depth, 0);
}

TEST_F(CoreTest, RingOverflowIsCountedAndReported) {
  hello();
  ASSERT_EQ(answer(command(configure_msg(1000, 100, 1, 1, 300, 1000))).type, MessageType::kAck);
  const auto count_events = [](const std::vector<Message>& msgs) {
    std::size_t n = 0;
    for (const Message& m : msgs)
      n += m.type == MessageType::kTriggerEdge || m.type == MessageType::kAdcSample;
    return n;
  };
  const std::size_t before = count_events(command(make_message(MessageType::kStart, 0)));
  hal.usb_stalled = true;  // host stops reading: events pile up in the ring
  run_until(hal, fw, hal.now + 301'000);
  EXPECT_EQ(fw.buffer_fill(), kEventCapacity);
  const std::uint32_t dropped = fw.dropped_events();
  EXPECT_GT(dropped, 300u);
  hal.usb_stalled = false;
  run_until(hal, fw, hal.now + 1'100'000);  // until a heartbeat has gone out
  const std::vector<Message> msgs = received(hal, host);
  std::uint32_t overrun_detail = 0, heartbeat_dropped = 0;
  for (const Message& m : msgs) {
    if (m.type == MessageType::kError && m.error.code == ErrorCode::kOverrun)
      overrun_detail += m.error.detail;
    if (m.type == MessageType::kHeartbeat) heartbeat_dropped = m.heartbeat.dropped_events;
  }
  // 300 edges x (1 edge + 1 sample) = 600 events: every one is either delivered or counted.
  EXPECT_EQ(before + count_events(msgs) + dropped, 600u);
  // Delivered after the stall: the full ring plus at most the one frame already being sent.
  EXPECT_GE(count_events(msgs), kEventCapacity);
  EXPECT_LE(count_events(msgs), kEventCapacity + 1);
  EXPECT_EQ(overrun_detail, dropped);
  EXPECT_EQ(heartbeat_dropped, dropped);
  EXPECT_EQ(fw.buffer_fill(), 0u);
}

TEST_F(CoreTest, LateInterruptsAreMeasuredWithoutAccumulatingDrift) {
  hello();
  hal.isr_latency_us = 60;  // above kLateEdgeThresholdUs (42 µs)
  ASSERT_EQ(answer(command(configure_msg(1000, 200, 1, 0, 20))).type, MessageType::kAck);
  ASSERT_EQ(answer(command(make_message(MessageType::kStart, 0))).type, MessageType::kAck);
  run_until(hal, fw, hal.now + 25'000);
  const std::vector<Message> msgs = received(hal, host);
  std::vector<std::uint64_t> rises;
  for (const GpioWrite& w : hal.gpio)
    if (w.high) rises.push_back(w.t_us);
  ASSERT_EQ(rises.size(), 20u);
  // Schedule is absolute: every edge is exactly 60 µs late, none later.
  for (std::size_t k = 1; k < rises.size(); ++k) EXPECT_EQ(rises[k] - rises[0], 1000 * k);
  std::size_t late_reports = 0;
  for (const Message& m : msgs) {
    if (m.type == MessageType::kTriggerEdge) {
      EXPECT_EQ(m.edge.lateness_us, 60);
    }
    if (m.type == MessageType::kError && m.error.code == ErrorCode::kLateEdge) {
      ++late_reports;
      EXPECT_EQ(m.error.detail, 60u);
    }
  }
  EXPECT_GE(late_reports, 1u);
}

TEST_F(CoreTest, StuckAdcIsReportedAsTimeout) {
  hello();
  hal.adc_never_completes = true;
  ASSERT_EQ(answer(command(configure_msg(1000, 200, 1, 1, 3))).type, MessageType::kAck);
  ASSERT_EQ(answer(command(make_message(MessageType::kStart, 0))).type, MessageType::kAck);
  run_until(hal, fw, hal.now + 5'000);
  std::uint32_t timeouts = 0;
  for (const Message& m : received(hal, host))
    if (m.type == MessageType::kError && m.error.code == ErrorCode::kAdcTimeout)
      timeouts += m.error.detail;
  EXPECT_EQ(timeouts, 2u);  // edges 1 and 2 found edge 0's / 1's conversion still pending
}

TEST_F(CoreTest, CorruptHostFrameIsReportedAndTheNextOneWorks) {
  Message m = make_message(MessageType::kHello, 9);
  std::uint8_t buf[kMaxFrameSize];
  const std::size_t n = encode_frame(m, buf, sizeof buf);
  buf[3] ^= 0x01;
  hal.to_device.insert(hal.to_device.end(), buf, buf + n);
  run_until(hal, fw, hal.now + 300);
  std::vector<Message> msgs = received(hal, host);
  ASSERT_EQ(msgs.size(), 1u);
  EXPECT_EQ(msgs[0].type, MessageType::kError);
  EXPECT_EQ(msgs[0].error.code, ErrorCode::kHostFrameBad);
  EXPECT_EQ(msgs[0].error.detail, static_cast<std::uint32_t>(DecodeError::kCrc));
  hello();
  EXPECT_EQ(fw.host_frames_bad(), 1u);
}

TEST_F(CoreTest, HeartbeatsAtTheConfiguredPeriodOnlyAfterHello) {
  run_until(hal, fw, hal.now + 500'000);
  EXPECT_TRUE(received(hal, host).empty());  // link not up: silent
  hello();
  ASSERT_EQ(answer(command(configure_msg(1000, 100, 1, 0, 0, 20))).type, MessageType::kAck);
  const std::uint64_t t_start = hal.now;
  run_until(hal, fw, t_start + 1'000'000);
  std::vector<std::uint64_t> uptimes;
  for (const Message& m : received(hal, host))
    if (m.type == MessageType::kHeartbeat) {
      uptimes.push_back(m.heartbeat.uptime_us);
      EXPECT_EQ(m.heartbeat.state, SequencerState::kConfigured);
      EXPECT_EQ(m.heartbeat.buffer_capacity, kEventCapacity);
    }
  // 1 s / 20 ms = 50 heartbeats; the period is measured from the main loop (100 µs granularity).
  ASSERT_GE(uptimes.size(), 49u);
  ASSERT_LE(uptimes.size(), 50u);
  for (std::size_t i = 1; i < uptimes.size(); ++i) {
    EXPECT_GE(uptimes[i] - uptimes[i - 1], 20'000u);
    EXPECT_LE(uptimes[i] - uptimes[i - 1], 20'100u);
  }
}

TEST(SpscRing, FullEmptyAndWrapAround) {
  SpscRing<int, 4> ring(0xFFFFFFFEu);  // indices cross 2^32 during the test
  int v = 0;
  EXPECT_FALSE(ring.pop(&v));
  for (int round = 0; round < 3; ++round) {
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(ring.push(round * 10 + i));
    EXPECT_FALSE(ring.push(99));
    EXPECT_EQ(ring.size(), 4u);
    for (int i = 0; i < 4; ++i) {
      ASSERT_TRUE(ring.pop(&v));
      EXPECT_EQ(v, round * 10 + i);
    }
    EXPECT_TRUE(ring.empty());
  }
}

TEST(SpscRing, ConcurrentProducerConsumerKeepsOrder) {
  // One producer thread, one consumer thread (as ISR and main loop): every value arrives once, in
  // order (run under TSan/ASan in the sanitizer build).
  static SpscRing<std::uint32_t, 64> ring;
  constexpr std::uint32_t kCount = 50'000;
  std::thread producer([] {
    for (std::uint32_t i = 0; i < kCount;)
      if (ring.push(i)) ++i;
  });
  std::uint32_t expected = 0;
  while (expected < kCount) {
    std::uint32_t v;
    if (ring.pop(&v)) {
      ASSERT_EQ(v, expected);
      ++expected;
    }
  }
  producer.join();
  EXPECT_TRUE(ring.empty());
}

}  // namespace
}  // namespace hc::fw
