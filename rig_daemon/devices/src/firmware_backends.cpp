// The "firmware" backends: trigger and FSR on the trigger/FSR firmware through firmware_host's host
// driver (one board, shared by both through fw::SharedFirmwareDevice; the board is the in-process
// firmware simulator for `device: sim`, a USB board for `device: usb[:VID:PID[:SERIAL]]`).
//
// Indices: the firmware numbers edges from 0 within each pulse train; both backends turn that into
// one running index since activation by noticing when a new train starts (the edge index does not
// increase), so a frame's trigger_index and the FSR sample's trigger_index agree.
//
// Given a SimulatedBoardInput (the rig has a simulated world), the simulated board's ADC reads the
// probe force through the default FsrCalibration (the FSR's power law), so the FSR reports the
// specimen force.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

#include "firmware_host/driver/shared_device.h"
#include "rig_daemon/devices/registry.h"

namespace hc::devices {

namespace {

// The options both backends read: which board, and how the simulated one behaves.
struct BoardOptions {
  std::string device = "sim";
  std::string sim_clock;  // "virtual" | "real_time"; default from the device's Clock
  double adc_noise_v = 0.0;
  std::uint64_t seed = 1;

  void read(ConfigNode node) {
    node.optional("device", device);
    node.optional("sim_clock", sim_clock, {"virtual", "real_time"});
    node.optional("adc_noise_v", adc_noise_v, Bounds::non_negative());
    node.optional("seed", seed);
  }

  Result<std::shared_ptr<fw::SharedFirmwareDevice>> acquire(
      const DeviceContext& ctx, const SimulatedBoardInput& input) const {
    fw::OpenOptions open;
    open.device = device;
    const bool simulated = ctx.clock && ctx.clock->is_simulated();
    open.sim_clock = (sim_clock.empty() ? simulated : sim_clock == "virtual")
                         ? fw::SimClock::kVirtual
                         : fw::SimClock::kRealTime;
    open.sim.adc_noise_v = adc_noise_v;
    open.sim.seed = input.seed ? input.seed(ctx.name + "/adc") : seed;
    if (input.force_n) {
      // Firmware µs since the board opened → host time; force → raw through the default FSR
      // power law → volts at the ADC pin.
      const std::int64_t epoch = ctx.clock->now_ns();
      const double vref = open.sim.adc_reference_v;
      const double full = std::ldexp(1.0, open.sim.adc_bits) - 1.0;
      open.sim.adc_source = [force_n = input.force_n, epoch, vref, full](std::uint8_t,
                                                                         std::uint64_t t_us) {
        FsrCalibration cal;
        cal.full_scale = full;
        const double force = force_n(epoch + static_cast<std::int64_t>(t_us) * 1000);
        return std::clamp(cal.to_raw(force) / full * vref, 0.0, vref);
      };
    }
    HC_RETURN_IF_ERROR(open.validate());
    return fw::SharedFirmwareDevice::acquire(open);
  }
};

// Running index across pulse trains (see the file comment).
class TrainIndex {
 public:
  std::uint64_t map(std::uint32_t edge_index) {
    if (have_last_ && edge_index <= last_) base_ += std::uint64_t{last_} + 1;
    have_last_ = true;
    last_ = edge_index;
    return base_ + edge_index;
  }
  void reset() {
    base_ = 0;
    last_ = 0;
    have_last_ = false;
  }
  // Indices skipped since the previous edge of the same train (lost edges).
  std::uint64_t gap(std::uint32_t edge_index) const {
    return have_last_ && edge_index > last_ + 1 ? edge_index - last_ - 1 : 0;
  }

 private:
  std::uint64_t base_ = 0;
  std::uint32_t last_ = 0;
  bool have_last_ = false;
};

std::chrono::microseconds to_us(Duration d) {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::max(d, Duration(0)));
}

Status board_error(const Status& s) {
  // A failed board link is a device failure whatever code the driver chose.
  if (s.code() == StatusCode::kInvalidArgument || s.code() == StatusCode::kFailedPrecondition)
    return s;
  return Status(StatusCode::kUnavailable, "firmware board: " + s.message());
}

// ------------------------------------------------------------------------------------------------
class FirmwareTrigger final : public Trigger {
 public:
  FirmwareTrigger(const DeviceContext& ctx, SimulatedBoardInput input)
      : Trigger(ctx), input_(std::move(input)) {}

  bool running() const override { return running_; }
  std::vector<std::uint32_t> lines() const override { return lines_; }

 protected:
  Status on_configure(ConfigNode node) override {
    board_.read(node);
    node.optional("lines", lines_);
    node.optional("adc_channels", adc_channels_);
    node.optional("heartbeat_ms", heartbeat_ms_, Bounds::between(fw::kMinHeartbeatPeriodMs, 10000));
    double late_s = 200e-6;
    node.optional("late_after_s", late_s, Bounds::positive());
    late_us_ = static_cast<std::uint32_t>(std::llround(late_s * 1e6));
    if (lines_.empty()) node.error("lines", "needs at least one line");
    for (std::uint32_t l : lines_)
      if (l > 7) node.error("lines", "the firmware has at most 8 lines (0..7)");
    for (std::uint32_t c : adc_channels_)
      if (c > 7) node.error("adc_channels", "the firmware has at most 8 ADC channels (0..7)");
    return node.status();
  }
  Status on_activate() override {
    Result<std::shared_ptr<fw::SharedFirmwareDevice>> b = board_.acquire(context(), input_);
    if (!b.ok()) return board_error(b.status());
    dev_ = std::move(b).value();
    index_.reset();
    running_ = false;
    return {};
  }
  Status on_deactivate() override {
    if (dev_) (void)dev_->stop();
    dev_.reset();
    running_ = false;
    return {};
  }
  Status on_reset() override {
    dev_.reset();
    return {};
  }
  Status on_start(const PulseTrain& train) override {
    fw::TriggerConfig cfg = base_config();
    cfg.period_us = static_cast<std::uint32_t>(std::llround(1e6 / train.rate_hz));
    cfg.pulse_width_us = std::max<std::uint32_t>(
        1, static_cast<std::uint32_t>(std::llround(train.pulse_width_s * 1e6)));
    if (train.count > 0xFFFFFFFFu) return invalid_argument("pulse train: count above 2^32 - 1");
    cfg.count = static_cast<std::uint32_t>(train.count);
    return run(cfg);
  }
  Status on_stop() override {
    running_ = false;
    Status s = dev_->stop();
    return s.ok() ? s : board_error(s);
  }
  Status on_fire() override {
    fw::TriggerConfig cfg = base_config();
    cfg.period_us = 2000;
    cfg.pulse_width_us = 1000;
    cfg.count = 1;
    return run(cfg);
  }
  Result<std::size_t> on_read(std::vector<TriggerEdge>& out, Duration timeout) override {
    std::vector<fw::TriggerEdgeEvent> events;
    Result<std::size_t> n = dev_->read_edges(events, to_us(timeout));
    if (!n.ok()) return board_error(n.status());
    const std::size_t before = out.size();
    for (const fw::TriggerEdgeEvent& e : events) {
      count_lost(index_.gap(e.edge_index) * lines_.size());
      const std::uint64_t index = index_.map(e.edge_index);
      if (e.lateness_us > late_us_) count_late(1);
      ++edges_in_train_;
      if (count_ && edges_in_train_ >= count_) running_ = false;
      for (std::uint32_t line : lines_) {
        if (!(e.lines_mask & (1u << line))) continue;
        TriggerEdge edge;
        edge.index = index;
        edge.line = line;
        edge.rising = true;
        edge.host_ns = e.host_time_ns;
        edge.device_stamp_ns = static_cast<std::int64_t>(e.device_time_us) * 1000;
        edge.device_counter = e.edge_index;
        out.push_back(edge);
      }
    }
    for (const fw::DeviceErrorEvent& err : dev_->take_errors())
      if (err.report.code == fw::ErrorCode::kOverrun ||
          err.report.code == fw::ErrorCode::kTxOverflow)
        count_lost(err.report.detail);
    return out.size() - before;
  }
  void describe(DeviceInfo& info) const override {
    info.model = "Hardcopy trigger/FSR firmware";
    if (dev_) {
      const fw::DeviceInfo d = dev_->info();
      info.serial = d.transport;
      info.details = {{"firmware", std::to_string(d.hello.firmware_major) + "." +
                                       std::to_string(d.hello.firmware_minor) + "." +
                                       std::to_string(d.hello.firmware_patch)},
                      {"lines", std::to_string(d.hello.num_trigger_lines)}};
    }
  }

 private:
  fw::TriggerConfig base_config() const {
    fw::TriggerConfig cfg;
    cfg.lines_mask = 0;
    for (std::uint32_t l : lines_)
      cfg.lines_mask = static_cast<std::uint8_t>(cfg.lines_mask | (1u << l));
    cfg.adc_channels_mask = 0;
    for (std::uint32_t c : adc_channels_)
      cfg.adc_channels_mask = static_cast<std::uint8_t>(cfg.adc_channels_mask | (1u << c));
    cfg.heartbeat_period_ms = heartbeat_ms_;
    return cfg;
  }
  Status run(const fw::TriggerConfig& cfg) {
    fw::DeviceInfo info = dev_->info();
    HC_RETURN_IF_ERROR(cfg.validate(&info.hello));
    // A finished train leaves the sequencer busy until stopped (stop() is idempotent).
    Status s = dev_->stop();
    if (s.ok()) s = dev_->configure_trigger(cfg);
    if (s.ok()) s = dev_->start();
    if (!s.ok()) return board_error(s);
    running_ = true;
    count_ = cfg.count;
    edges_in_train_ = 0;
    return {};
  }

  SimulatedBoardInput input_;
  BoardOptions board_;
  std::vector<std::uint32_t> lines_{0};
  std::vector<std::uint32_t> adc_channels_{0};
  std::uint16_t heartbeat_ms_ = 100;
  std::uint32_t late_us_ = 200;
  std::shared_ptr<fw::SharedFirmwareDevice> dev_;
  TrainIndex index_;
  bool running_ = false;
  std::uint32_t count_ = 0;
  std::uint32_t edges_in_train_ = 0;
};

// ------------------------------------------------------------------------------------------------
class FirmwareFsr final : public Fsr {
 public:
  FirmwareFsr(const DeviceContext& ctx, SimulatedBoardInput input)
      : Fsr(ctx), input_(std::move(input)) {}

  FsrCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return 0.0; }  // one sample per trigger edge

 protected:
  Status on_configure(ConfigNode node) override {
    board_.read(node);
    node.optional("channel", channel_, Bounds::between(0, 7));
    read_calibration(node, &cal_);
    return node.status();
  }
  Status on_activate() override {
    Result<std::shared_ptr<fw::SharedFirmwareDevice>> b = board_.acquire(context(), input_);
    if (!b.ok()) return board_error(b.status());
    dev_ = std::move(b).value();
    index_.reset();
    sequence_ = 0;
    return {};
  }
  Status on_deactivate() override {
    dev_.reset();
    return {};
  }
  Status on_reset() override {
    dev_.reset();
    return {};
  }
  Result<std::size_t> on_read(std::vector<FsrSample>& out, Duration timeout) override {
    std::vector<fw::AdcSampleEvent> events;
    Result<std::size_t> n = dev_->read_samples(events, to_us(timeout));
    if (!n.ok()) return board_error(n.status());
    const std::size_t before = out.size();
    for (const fw::AdcSampleEvent& e : events) {
      if (e.channel != channel_) continue;
      count_lost(index_.gap(e.edge_index));
      FsrSample s;
      s.trigger_index = index_.map(e.edge_index);
      s.raw = e.raw;
      s.force_n = cal_.to_newtons(e.raw);
      s.channel = e.channel;
      s.sequence = sequence_++;
      s.host_ns = e.host_time_ns;
      s.device_stamp_ns = static_cast<std::int64_t>(e.device_time_us) * 1000;
      out.push_back(s);
    }
    return out.size() - before;
  }
  void describe(DeviceInfo& info) const override {
    info.model = "Hardcopy trigger/FSR firmware ADC";
    info.details = {{"channel", std::to_string(channel_)}};
  }

 private:
  SimulatedBoardInput input_;
  BoardOptions board_;
  std::uint32_t channel_ = 0;
  FsrCalibration cal_;
  std::shared_ptr<fw::SharedFirmwareDevice> dev_;
  TrainIndex index_;
  std::uint64_t sequence_ = 0;
};

}  // namespace

Status register_firmware_backends(BackendRegistry& registry, SimulatedBoardInput input) {
  HC_RETURN_IF_ERROR(registry.add<Trigger>(
      "firmware",
      [input](const DeviceContext& ctx) -> Result<std::unique_ptr<Trigger>> {
        return std::unique_ptr<Trigger>(std::make_unique<FirmwareTrigger>(ctx, input));
      },
      "trigger lines of the trigger/FSR firmware (USB or its simulator)"));
  HC_RETURN_IF_ERROR(registry.add<Fsr>(
      "firmware",
      [input](const DeviceContext& ctx) -> Result<std::unique_ptr<Fsr>> {
        return std::unique_ptr<Fsr>(std::make_unique<FirmwareFsr>(ctx, input));
      },
      "FSR on the trigger/FSR firmware's edge-synchronised ADC"));
  return {};
}

}  // namespace hc::devices
