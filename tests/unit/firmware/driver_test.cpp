// Host driver end to end through the simulator (same API as the USB device): exact trigger timing,
// synchronised samples, heartbeats, device errors, link faults; plus the libusb error paths (no
// hardware here) and handshake failures over a scripted transport.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <numbers>

#include "firmware_host/core/firmware.h"
#include "firmware_host/driver/firmware_device.h"

namespace hc::fw {
namespace {

using namespace std::chrono_literals;

struct Collected {
  std::vector<TriggerEdgeEvent> edges;
  std::vector<AdcSampleEvent> samples;
  std::vector<HeartbeatStatus> heartbeats;
  std::vector<DeviceErrorEvent> errors;
};

void collect(const std::vector<Event>& events, Collected& c) {
  for (const Event& e : events) {
    switch (e.kind) {
      case Event::Kind::kTriggerEdge:
        c.edges.push_back(e.edge);
        break;
      case Event::Kind::kAdcSample:
        c.samples.push_back(e.sample);
        break;
      case Event::Kind::kHeartbeat:
        c.heartbeats.push_back(e.heartbeat);
        break;
      case Event::Kind::kError:
        c.errors.push_back(e.error);
        break;
    }
  }
}

// Polls until `duration` of virtual time has passed (poll returns early when events arrive).
Collected run_for(FirmwareDevice& dev, std::chrono::microseconds duration) {
  Collected c;
  std::vector<Event> events;
  Simulator& sim = *dev.simulator();
  const std::uint64_t end = sim.now_us() + static_cast<std::uint64_t>(duration.count());
  while (sim.now_us() < end) {
    events.clear();
    auto n = dev.poll(events, std::chrono::microseconds(end - sim.now_us()));
    EXPECT_TRUE(n.ok()) << n.status().to_string();
    collect(events, c);
  }
  return c;
}

// A force source: an FSR divider voltage following a 20 Hz sine between 0.5 V and 2.5 V.
double fsr_volts(std::uint8_t channel, std::uint64_t t_us) {
  const double t = static_cast<double>(t_us) * 1e-6;
  return 1.5 + (channel + 1) * 0.5 * std::sin(2 * std::numbers::pi * 20.0 * t);
}

std::uint16_t quantise(double v) {  // 12-bit ADC on 3.3 V, as SimulatorOptions' defaults
  return static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0, 3.3) / 3.3 * 4095.0));
}

std::unique_ptr<FirmwareDevice> open_sim(SimulatorOptions sim = {}) {
  OpenOptions opts;
  opts.device = "sim";
  if (!sim.adc_source) sim.adc_source = fsr_volts;
  opts.sim = std::move(sim);
  auto dev = FirmwareDevice::open(opts);
  EXPECT_TRUE(dev.ok()) << dev.status().to_string();
  return dev.ok() ? std::move(dev).value() : nullptr;
}

TEST(FirmwareDriver, HandshakeReportsDevice) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  EXPECT_EQ(dev->info().hello.protocol_version, kProtocolVersion);
  EXPECT_EQ(dev->info().hello.num_trigger_lines, 4);
  EXPECT_EQ(dev->info().hello.adc_bits, 12);
  EXPECT_EQ(dev->info().transport, "sim (virtual clock)");
  EXPECT_NE(dev->simulator(), nullptr);
}

TEST(FirmwareDriver, NTriggersGiveNEdgesWithExactPeriodsAndNSynchronisedSamples) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 1'000;  // 1 kHz, the FSR rate in the issue
  cfg.pulse_width_us = 100;
  cfg.lines_mask = 0b0111;  // three cameras
  cfg.adc_channels_mask = 0b0011;
  cfg.count = 500;
  cfg.heartbeat_period_ms = 50;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  const Collected c = run_for(*dev, 600ms);

  ASSERT_EQ(c.edges.size(), 500u);
  ASSERT_EQ(c.samples.size(), 1000u);
  for (std::size_t k = 0; k < c.edges.size(); ++k) {
    EXPECT_EQ(c.edges[k].edge_index, k);
    EXPECT_EQ(c.edges[k].lines_mask, 0b0111);
    EXPECT_EQ(c.edges[k].device_time_us - c.edges[0].device_time_us, 1'000 * k);
    EXPECT_EQ(c.edges[k].lateness_us, 0);
  }
  // Samples: one per channel per edge, taken at the edge (channel 1 after channel 0's 5 µs
  // conversion), with the value the source had then.
  for (std::size_t i = 0; i < c.samples.size(); ++i) {
    const AdcSampleEvent& s = c.samples[i];
    const std::size_t k = i / 2;
    EXPECT_EQ(s.edge_index, k);
    EXPECT_EQ(s.channel, i % 2);
    EXPECT_EQ(s.device_time_us, c.edges[k].device_time_us + 5 * (i % 2));
    EXPECT_EQ(s.raw, quantise(fsr_volts(s.channel, s.device_time_us)));
  }
  // The virtual lines saw exactly those pulses.
  const auto& gpio = dev->simulator()->gpio_edges();
  ASSERT_EQ(gpio.size(), 500u * 2 * 3);
  for (std::size_t k = 0; k < 500; ++k)
    for (std::size_t line = 0; line < 3; ++line) {
      const GpioEdge& rise = gpio[6 * k + line];
      const GpioEdge& fall = gpio[6 * k + 3 + line];
      EXPECT_TRUE(rise.high);
      EXPECT_EQ(rise.line, line);
      EXPECT_EQ(rise.t_us, c.edges[k].device_time_us);
      EXPECT_FALSE(fall.high);
      EXPECT_EQ(fall.t_us, c.edges[k].device_time_us + 100);
    }
  // Host time mapping: the mapped time never follows the receive time and lags it by < 1 ms (the
  // association error bound; the true host time of an edge lies in [host_time_ns - 0, host_rx_ns]).
  std::int64_t max_latency_ns = 0;
  for (const TriggerEdgeEvent& e : c.edges) {
    EXPECT_LE(e.host_time_ns, e.host_rx_ns);
    max_latency_ns = std::max(max_latency_ns, e.host_rx_ns - e.host_time_ns);
  }
  EXPECT_LT(max_latency_ns, 1'000'000);
  std::printf("[ measured ] max edge receive latency over mapped time: %.1f us\n",
              static_cast<double>(max_latency_ns) / 1e3);
  const LinkStats stats = dev->link_stats();
  EXPECT_EQ(stats.frames_corrupt, 0u);
  EXPECT_EQ(stats.frames_lost, 0u);
  EXPECT_EQ(stats.device_errors, 0u);
  ASSERT_TRUE(dev->last_heartbeat().has_value());
  EXPECT_EQ(dev->last_heartbeat()->heartbeat.state, SequencerState::kDone);
  EXPECT_EQ(dev->last_heartbeat()->heartbeat.edges_emitted, 500u);
}

TEST(FirmwareDriver, HeartbeatsArriveAtTheConfiguredPeriod) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.heartbeat_period_ms = 20;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  const Collected c = run_for(*dev, 1s);
  ASSERT_GE(c.heartbeats.size(), 49u);
  ASSERT_LE(c.heartbeats.size(), 51u);
  for (std::size_t i = 1; i < c.heartbeats.size(); ++i) {
    const std::uint64_t dt =
        c.heartbeats[i].heartbeat.uptime_us - c.heartbeats[i - 1].heartbeat.uptime_us;
    EXPECT_GE(dt, 20'000u);
    EXPECT_LE(dt, 20'100u);  // main loop granularity: 100 µs
    EXPECT_EQ(c.heartbeats[i].heartbeat.state, SequencerState::kConfigured);
    EXPECT_EQ(c.heartbeats[i].heartbeat.buffer_capacity, kEventCapacity);
  }
}

TEST(FirmwareDriver, CommandErrorsAreClearStatuses) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  Status st = dev->start();
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("not configured"), std::string::npos) << st.message();

  TriggerConfig bad;
  bad.pulse_width_us = bad.period_us;
  st = dev->configure_trigger(bad);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("pulse_width_us"), std::string::npos) << st.message();
  bad = TriggerConfig{};
  bad.lines_mask = 0x10;  // the simulated device has 4 lines
  st = dev->configure_trigger(bad);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("lines_mask"), std::string::npos) << st.message();

  TriggerConfig cfg;
  cfg.period_us = 10'000;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  st = dev->configure_trigger(cfg);
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("busy"), std::string::npos) << st.message();
  ASSERT_TRUE(dev->stop().ok());
  ASSERT_TRUE(dev->stop().ok());  // idempotent
}

TEST(FirmwareDriver, DeviceOverrunIsReportedWithExactCounts) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 1'000;
  cfg.pulse_width_us = 100;
  cfg.adc_channels_mask = 0b0001;
  cfg.count = 400;
  cfg.heartbeat_period_ms = 50;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  Collected c = run_for(*dev, 50ms);
  dev->simulator()->set_usb_stalled(true);  // the host side stops draining the endpoint
  dev->simulator()->advance_by(300'000);
  dev->simulator()->set_usb_stalled(false);
  const Collected rest = run_for(*dev, 200ms);
  c.edges.insert(c.edges.end(), rest.edges.begin(), rest.edges.end());
  c.samples.insert(c.samples.end(), rest.samples.begin(), rest.samples.end());
  std::uint64_t reported = 0;
  for (const DeviceErrorEvent& e : rest.errors) {
    ASSERT_EQ(e.report.code, ErrorCode::kOverrun) << e.message();
    reported += e.report.detail;
    EXPECT_NE(e.message().find("events dropped"), std::string::npos);
  }
  const std::uint32_t dropped = dev->simulator()->firmware().dropped_events();
  EXPECT_GT(dropped, 0u);
  EXPECT_EQ(reported, dropped);
  ASSERT_TRUE(dev->last_heartbeat().has_value());
  EXPECT_EQ(dev->last_heartbeat()->heartbeat.dropped_events, dropped);
  // Every one of the 800 events was delivered or counted as dropped; nothing was lost on the link.
  EXPECT_EQ(c.edges.size() + c.samples.size() + dropped, 800u);
  EXPECT_EQ(dev->link_stats().frames_lost, 0u);
}

TEST(FirmwareDriver, LateEdgesAreReported) {
  SimulatorOptions sim;
  sim.isr_latency_us = 50;
  auto dev = open_sim(sim);
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 2'000;
  cfg.count = 10;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  const Collected c = run_for(*dev, 40ms);
  ASSERT_EQ(c.edges.size(), 10u);
  for (std::size_t k = 0; k < c.edges.size(); ++k) {
    EXPECT_EQ(c.edges[k].lateness_us, 50);
    EXPECT_EQ(c.edges[k].device_time_us - c.edges[0].device_time_us, 2'000 * k);
  }
  ASSERT_FALSE(c.errors.empty());
  EXPECT_EQ(c.errors[0].report.code, ErrorCode::kLateEdge);
  EXPECT_EQ(c.errors[0].report.detail, 50u);
}

TEST(FirmwareDriver, CorruptedAndDroppedBytesMidStreamResyncAndAreCounted) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 1'000;
  cfg.pulse_width_us = 100;
  cfg.adc_channels_mask = 0b0001;
  cfg.count = 300;
  cfg.heartbeat_period_ms = 1000;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  Simulator& sim = *dev->simulator();
  const std::uint64_t base = sim.in_bytes_sent();
  // Frames are >= 20 bytes, so these hit four different frames.
  sim.corrupt_in_byte(base + 500, 0x5A);
  sim.corrupt_in_byte(base + 2'000, 0xFF);  // may turn a byte into a delimiter: splits the frame
  sim.corrupt_in_byte(base + 4'000, 0x01);
  sim.drop_in_byte(base + 6'000);
  ASSERT_TRUE(dev->start().ok());
  const Collected c = run_for(*dev, 350ms);
  const LinkStats stats = dev->link_stats();
  // Each fault destroys exactly one frame (two halves of a split frame both fail: counted as
  // corrupt twice but lost once); the stream resynchronises at the next delimiter.
  EXPECT_EQ(stats.frames_lost, 4u);
  EXPECT_GE(stats.frames_corrupt, 4u);
  EXPECT_LE(stats.frames_corrupt, 5u);
  EXPECT_GT(stats.bytes_discarded, 0u);
  EXPECT_EQ(c.edges.size() + c.samples.size(), 600u - 4u);
  // Whatever arrived is intact: edge k at t0 + k ms, samples tied to existing edges.
  const std::uint64_t t0 = c.edges[0].edge_index == 0
                               ? c.edges[0].device_time_us
                               : c.edges[1].device_time_us - 1'000 * c.edges[1].edge_index;
  for (const TriggerEdgeEvent& e : c.edges) EXPECT_EQ(e.device_time_us, t0 + 1'000 * e.edge_index);
  for (const AdcSampleEvent& s : c.samples) {
    EXPECT_EQ(s.device_time_us, t0 + 1'000 * s.edge_index);
    EXPECT_EQ(s.raw, quantise(fsr_volts(0, s.device_time_us)));
  }
}

TEST(FirmwareDriver, NoiseIsSeededAndHasTheConfiguredSpread) {
  const auto sample_run = [](std::uint64_t seed) {
    SimulatorOptions sim;
    sim.seed = seed;
    sim.adc_noise_v = 0.01;
    sim.adc_source = [](std::uint8_t, std::uint64_t) { return 1.65; };
    auto dev = open_sim(sim);
    TriggerConfig cfg;
    cfg.period_us = 500;
    cfg.pulse_width_us = 50;
    cfg.count = 2'000;
    EXPECT_TRUE(dev->configure_trigger(cfg).ok());
    EXPECT_TRUE(dev->start().ok());
    std::vector<std::uint16_t> raw;
    for (const AdcSampleEvent& s : run_for(*dev, 1100ms).samples) raw.push_back(s.raw);
    return raw;
  };
  const std::vector<std::uint16_t> a = sample_run(5), b = sample_run(5), other = sample_run(6);
  ASSERT_EQ(a.size(), 2'000u);
  EXPECT_EQ(a, b);  // deterministic for a seed
  EXPECT_NE(a, other);
  double mean = 0, var = 0;
  for (std::uint16_t v : a) mean += v;
  mean /= static_cast<double>(a.size());
  for (std::uint16_t v : a) var += (v - mean) * (v - mean);
  const double sd = std::sqrt(var / static_cast<double>(a.size() - 1));
  // Expected: mean 1.65 / 3.3 * 4095 = 2047.5 counts, sd 0.01 / 3.3 * 4095 = 12.41 counts
  // (quantisation adds 1/12 count^2, negligible); tolerances ~5 standard errors.
  EXPECT_NEAR(mean, 2047.5, 1.5);
  EXPECT_NEAR(sd, 12.41, 1.0);
}

TEST(FirmwareDriver, RealTimeSimulatorClockFollowsTheHost) {
  OpenOptions opts;
  opts.sim_clock = SimClock::kRealTime;
  auto opened = FirmwareDevice::open(opts);
  ASSERT_TRUE(opened.ok()) << opened.status().to_string();
  FirmwareDevice& dev = **opened;
  EXPECT_EQ(dev.info().transport, "sim (real-time clock)");
  TriggerConfig cfg;
  cfg.period_us = 10'000;  // 100 Hz
  cfg.count = 10;
  ASSERT_TRUE(dev.configure_trigger(cfg).ok());
  const std::int64_t t_start = host_monotonic_ns();
  ASSERT_TRUE(dev.start().ok());
  Collected c;
  std::vector<Event> events;
  while (c.edges.size() < 10 && host_monotonic_ns() - t_start < 2'000'000'000) {
    events.clear();
    ASSERT_TRUE(dev.poll(events, 20ms).ok());
    collect(events, c);
  }
  ASSERT_EQ(c.edges.size(), 10u);
  // 10 edges 10 ms apart take >= 90 ms of wall time.
  EXPECT_GE(host_monotonic_ns() - t_start, 90'000'000);
  for (std::size_t k = 0; k < 10; ++k)
    EXPECT_EQ(c.edges[k].device_time_us - c.edges[0].device_time_us, 10'000 * k);
}

TEST(FirmwareDriver, UsbSpecParsing) {
  auto spec = parse_usb_spec("usb");
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(spec->vendor_id, kUsbVendorId);
  EXPECT_EQ(spec->product_id, kUsbProductId);
  spec = parse_usb_spec("usb:06c2:0045:ABC123");
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(spec->vendor_id, 0x06C2);
  EXPECT_EQ(spec->product_id, 0x0045);
  EXPECT_EQ(spec->serial, "ABC123");
  for (const char* bad : {"usb:", "usb:1209", "usb:12g9:0001", "usb:12345:0001",
                          "usb:1209:0001:", "serial:/dev/ttyACM0", "", "simulator"}) {
    const auto r = parse_usb_spec(bad);
    EXPECT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << bad;
  }
  OpenOptions opts;
  opts.device = "usb:xyz";
  EXPECT_EQ(FirmwareDevice::open(opts).status().code(), StatusCode::kInvalidArgument);
}

TEST(FirmwareDriver, NoUsbDeviceGivesAClearStatus) {
  // No firmware board is attached to CI machines: opening must fail cleanly, naming the device.
  OpenOptions opts;
  opts.device = "usb";
  auto dev = FirmwareDevice::open(opts);
  ASSERT_FALSE(dev.ok());
  const StatusCode code = dev.status().code();
  EXPECT_TRUE(code == StatusCode::kNotFound || code == StatusCode::kUnavailable)
      << dev.status().to_string();
  EXPECT_NE(dev.status().message().find("1209:0001"), std::string::npos) << dev.status().message();
  opts.device = "usb:1209:0001:NO-SUCH-SERIAL";
  dev = FirmwareDevice::open(opts);
  ASSERT_FALSE(dev.ok());
  EXPECT_NE(dev.status().message().find("NO-SUCH-SERIAL"), std::string::npos)
      << dev.status().message();
}

// A transport scripted by the test: replies with canned bytes, or fails.
class ScriptedTransport final : public Transport {
 public:
  std::deque<std::uint8_t> incoming;
  std::vector<std::uint8_t> written;
  bool fail_reads = false;
  std::int64_t now = 1'000'000'000;
  Status write(const std::uint8_t* data, std::size_t size) override {
    written.insert(written.end(), data, data + size);
    return {};
  }
  Result<std::size_t> read(std::uint8_t* out, std::size_t cap,
                           std::chrono::microseconds timeout) override {
    if (fail_reads) return Status(StatusCode::kUnavailable, "usb read: LIBUSB_ERROR_NO_DEVICE");
    std::size_t n = 0;
    while (n < cap && !incoming.empty()) {
      out[n++] = incoming.front();
      incoming.pop_front();
    }
    if (n == 0) now += timeout.count() * 1000;  // time passes while waiting
    return n;
  }
  std::int64_t now_ns() const override { return now; }
  std::string describe() const override { return "scripted"; }
  void queue(const Message& m) {
    std::uint8_t buf[kMaxFrameSize];
    const std::size_t n = encode_frame(m, buf, sizeof buf);
    incoming.insert(incoming.end(), buf, buf + n);
  }
};

TEST(FirmwareDriver, SilentDeviceTimesOut) {
  OpenOptions opts;
  opts.command_timeout = 50ms;
  auto t = std::make_unique<ScriptedTransport>();
  const auto dev = FirmwareDevice::open(std::move(t), opts);
  ASSERT_FALSE(dev.ok());
  EXPECT_EQ(dev.status().code(), StatusCode::kDeadlineExceeded);
  EXPECT_NE(dev.status().message().find("Hello"), std::string::npos) << dev.status().message();
}

TEST(FirmwareDriver, ProtocolVersionMismatchIsRefused) {
  auto t = std::make_unique<ScriptedTransport>();
  Message reply = make_message(MessageType::kHelloReply, 0);
  reply.hello_reply.protocol_version = kProtocolVersion + 1;
  t->queue(reply);
  const auto dev = FirmwareDevice::open(std::move(t), OpenOptions{});
  ASSERT_FALSE(dev.ok());
  EXPECT_EQ(dev.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(dev.status().message().find("protocol version 2"), std::string::npos)
      << dev.status().message();
}

TEST(FirmwareDriver, LinkFailureSurfacesFromPoll) {
  auto owned = std::make_unique<ScriptedTransport>();
  ScriptedTransport* t = owned.get();
  Message reply = make_message(MessageType::kHelloReply, 0);
  reply.hello_reply.protocol_version = kProtocolVersion;
  reply.hello_reply.num_trigger_lines = 1;
  reply.hello_reply.num_adc_channels = 1;
  t->queue(reply);
  auto dev = FirmwareDevice::open(std::move(owned), OpenOptions{});
  ASSERT_TRUE(dev.ok()) << dev.status().to_string();
  // The driver sent a flush delimiter, then a valid Hello frame.
  ASSERT_GE(t->written.size(), 2u);
  EXPECT_EQ(t->written[0], 0);
  Message hello;
  ASSERT_EQ(decode_frame(t->written.data() + 1, t->written.size() - 2, &hello), DecodeError::kOk);
  EXPECT_EQ(hello.type, MessageType::kHello);
  EXPECT_EQ(hello.hello.protocol_version, kProtocolVersion);
  t->fail_reads = true;
  std::vector<Event> events;
  const auto n = (*dev)->poll(events, 10ms);
  ASSERT_FALSE(n.ok());
  EXPECT_EQ(n.status().code(), StatusCode::kUnavailable);
}

}  // namespace
}  // namespace hc::fw

namespace hc::fw {
namespace {

// Host-time mapping under crystal drift: the true host time of an edge is known exactly in the
// virtual-clock simulator (device µs / (1 + ppm·1e-6) after the transport's epoch), so the mapped
// host_time_ns can be checked against it. Target from the issue: association error < 1 ms.
void check_mapping_under_drift(double ppm) {
  SimulatorOptions sim;
  sim.clock_drift_ppm = ppm;
  auto dev = open_sim(sim);
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 10'000;  // 100 Hz for 30 s: 3 ms of accumulated drift at 100 ppm
  cfg.pulse_width_us = 1'000;
  cfg.count = 3'000;
  cfg.heartbeat_period_ms = 100;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  const Collected c = run_for(*dev, 31s);
  ASSERT_EQ(c.edges.size(), 3'000u);
  const double rate = 1.0 + ppm * 1e-6;
  const std::int64_t now_ns = dev->now_ns();
  const std::uint64_t now_us = dev->simulator()->now_us();
  double max_err_us = 0;
  for (const TriggerEdgeEvent& e : c.edges) {
    const double true_ns = static_cast<double>(now_ns) -
                           static_cast<double>(now_us - e.device_time_us) * 1000.0 / rate;
    max_err_us =
        std::max(max_err_us, std::abs(static_cast<double>(e.host_time_ns) - true_ns) / 1e3);
  }
  // Without drift tracking the error would reach 30 s x |ppm| = 3000 µs at the end.
  EXPECT_LT(max_err_us, 1'000.0) << ppm << " ppm";
  std::printf("[ measured ] %+.0f ppm drift over 30 s: max |host_time_ns - true| = %.1f us\n", ppm,
              max_err_us);
}

TEST(FirmwareDriver, HostTimeMappingTracksAFastCrystal) { check_mapping_under_drift(100.0); }
TEST(FirmwareDriver, HostTimeMappingTracksASlowCrystal) { check_mapping_under_drift(-100.0); }

}  // namespace
}  // namespace hc::fw

namespace hc::fw {
namespace {

TEST(FirmwareDriver, StuckAdcStopsSamplesAndIsReported) {
  auto dev = open_sim();
  ASSERT_TRUE(dev);
  TriggerConfig cfg;
  cfg.period_us = 1'000;
  cfg.pulse_width_us = 100;
  cfg.count = 100;
  ASSERT_TRUE(dev->configure_trigger(cfg).ok());
  ASSERT_TRUE(dev->start().ok());
  Collected c = run_for(*dev, 20ms);
  const std::size_t samples_before = c.samples.size();
  EXPECT_GE(samples_before, 15u);
  dev->simulator()->set_adc_stuck(true);
  const Collected stuck = run_for(*dev, 20ms);
  // At most the conversion already under way completes; then edges continue without samples.
  EXPECT_LE(stuck.samples.size(), 1u);
  EXPECT_GE(stuck.edges.size(), 19u);
  std::uint32_t abandoned = 0;
  for (const DeviceErrorEvent& e : stuck.errors) {
    EXPECT_EQ(e.report.code, ErrorCode::kAdcTimeout) << e.message();
    abandoned += e.report.detail;
  }
  // Every edge after the first stuck conversion finds the previous one still pending.
  EXPECT_GE(abandoned, stuck.edges.size() - 2);
  dev->simulator()->set_adc_stuck(false);
  const Collected recovered = run_for(*dev, 20ms);
  EXPECT_GE(recovered.samples.size(), 19u);  // conversions resume at the next edge
}

}  // namespace
}  // namespace hc::fw
