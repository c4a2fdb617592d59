// The simulator's virtual peripherals, driven with raw protocol frames (no driver in between).
#include <gtest/gtest.h>

#include "firmware_host/core/firmware.h"
#include "firmware_host/simulator/simulator.h"

namespace hc::fw {
namespace {

void send(Simulator& sim, Message m) {
  std::uint8_t buf[kMaxFrameSize];
  sim.host_write(buf, encode_frame(m, buf, sizeof buf));
}

std::vector<Message> read_all(Simulator& sim, StreamDecoder& d) {
  std::vector<std::uint8_t> bytes(sim.host_readable());
  bytes.resize(sim.host_read(bytes.data(), bytes.size()));
  std::vector<Message> out;
  const std::uint8_t* p = bytes.data();
  Message m;
  DecodeError e;
  for (;;) {
    const auto r = d.next(&p, bytes.data() + bytes.size(), &m, &e);
    if (r == StreamDecoder::Result::kNeedMore) break;
    if (r == StreamDecoder::Result::kMessage) out.push_back(m);
  }
  return out;
}

void start_train(Simulator& sim, std::uint8_t lines, std::uint8_t adc, std::uint32_t count) {
  send(sim, make_message(MessageType::kHello, 1));
  Message cfg = make_message(MessageType::kConfigureTrigger, 2);
  cfg.configure = {1'000, 250, lines, adc, count, 0};
  send(sim, cfg);
  send(sim, make_message(MessageType::kStart, 3));
}

TEST(Simulator, LinesRecordOnlyTheirOwnEdges) {
  Simulator sim;
  start_train(sim, 0b1010, 0, 3);
  sim.advance_to(10'000);
  const auto& edges = sim.gpio_edges();
  ASSERT_EQ(edges.size(), 12u);  // 3 pulses x 2 lines x (rise + fall)
  for (const GpioEdge& e : edges) EXPECT_TRUE(e.line == 1 || e.line == 3);
  // Rise/fall pairs 250 µs apart, pulses 1000 µs apart.
  EXPECT_EQ(edges[2].t_us - edges[0].t_us, 250u);
  EXPECT_EQ(edges[4].t_us - edges[0].t_us, 1'000u);
  EXPECT_EQ(sim.now_us(), 10'000u);
}

TEST(Simulator, AdcQuantisesAndClampsToTheReference) {
  SimulatorOptions opts;
  // Channel 0 over range, 1 under range, 2 at 1.0 V, 3 at exactly half scale.
  opts.adc_source = [](std::uint8_t ch, std::uint64_t) {
    const double v[4] = {5.0, -1.0, 1.0, 1.65};
    return v[ch];
  };
  Simulator sim(opts);
  start_train(sim, 1, 0b1111, 1);
  sim.advance_to(5'000);
  const auto& conv = sim.adc_conversions();
  ASSERT_EQ(conv.size(), 4u);
  EXPECT_EQ(conv[0].raw, 4095);
  EXPECT_EQ(conv[1].raw, 0);
  EXPECT_EQ(conv[2].raw, 1241);  // round(1.0 / 3.3 * 4095) = round(1240.9)
  EXPECT_EQ(conv[3].raw, 2048);  // round(2047.5) rounds half away from zero
  // Conversions run back to back, adc_conversion_us (5) apart.
  for (std::size_t i = 1; i < 4; ++i) EXPECT_EQ(conv[i].t_us - conv[i - 1].t_us, 5u);
  StreamDecoder d;
  std::size_t samples = 0;
  for (const Message& m : read_all(sim, d))
    if (m.type == MessageType::kAdcSample) {
      EXPECT_EQ(m.sample.raw, conv[m.sample.channel].raw);
      ++samples;
    }
  EXPECT_EQ(samples, 4u);
}

TEST(Simulator, StalledLinkHoldsBytesAndDropFaultRemovesOne) {
  Simulator sim;
  start_train(sim, 1, 1, 2);
  sim.set_usb_stalled(true);
  sim.advance_to(5'000);
  EXPECT_EQ(sim.host_readable(), 0u);
  EXPECT_EQ(sim.firmware().buffer_fill(), 4u);  // 2 edges + 2 samples waiting in the ring
  sim.drop_in_byte(sim.in_bytes_sent() + 40);
  sim.set_usb_stalled(false);
  sim.advance_to(6'000);
  const std::uint64_t sent = sim.in_bytes_sent();
  EXPECT_EQ(sim.host_readable(), sent - 1);
  StreamDecoder d;
  const std::vector<Message> msgs = read_all(sim, d);
  EXPECT_EQ(d.frames_bad(), 1u);
  EXPECT_EQ(msgs.size() + 1, sim.firmware().tx_frames());
}

}  // namespace
}  // namespace hc::fw

namespace hc::fw {
namespace {

TEST(Simulator, SameOptionsGiveByteIdenticalOutput) {
  const auto run = [](std::uint64_t seed) {
    SimulatorOptions opts;
    opts.seed = seed;
    opts.adc_noise_v = 0.05;
    opts.adc_source = [](std::uint8_t ch, std::uint64_t t_us) { return 0.5 + ch + 1e-7 * t_us; };
    Simulator sim(opts);
    start_train(sim, 0b0011, 0b0011, 200);
    sim.advance_to(250'000);
    std::vector<std::uint8_t> bytes(sim.host_readable());
    bytes.resize(sim.host_read(bytes.data(), bytes.size()));
    return bytes;
  };
  const std::vector<std::uint8_t> a = run(11);
  EXPECT_GT(a.size(), 200u * 3 * 20);  // 200 edges + 400 samples, >= 20 bytes a frame
  EXPECT_EQ(a, run(11));
  EXPECT_NE(a, run(12));  // the noise differs
}

}  // namespace
}  // namespace hc::fw
