#include "firmware_host/driver/firmware_device.h"

#include <algorithm>
#include <cmath>
#include <thread>

namespace hc::fw {
namespace {

using std::chrono::microseconds;

// The min-delay clock offset is kept over two rolling windows of this length, so it follows a
// crystal's drift (tens of ppm) with a lag of at most two windows.
constexpr std::int64_t kOffsetWindowNs = 2'000'000'000;

Status deadline_exceeded(std::string message) {
  return Status(StatusCode::kDeadlineExceeded, std::move(message));
}

// The in-process simulator as a byte pipe. kVirtual: time advances only while the driver reads,
// in main-loop-period steps so receive times are as fine as the device's own send times.
class SimTransport final : public Transport {
 public:
  SimTransport(SimulatorOptions options, SimClock clock)
      : sim_(std::move(options)),
        clock_(clock),
        epoch_ns_(host_monotonic_ns()),
        rate_(1.0 + sim_.options().clock_drift_ppm * 1e-6) {}

  Status write(const std::uint8_t* data, std::size_t size) override {
    sim_.host_write(data, size);
    return {};
  }

  Result<std::size_t> read(std::uint8_t* out, std::size_t cap, microseconds timeout) override {
    const auto timeout_us = static_cast<std::uint64_t>(std::max<std::int64_t>(0, timeout.count()));
    if (clock_ == SimClock::kVirtual) {
      const std::int64_t deadline_ns = now_ns() + static_cast<std::int64_t>(timeout_us) * 1000;
      // At least 1 µs of progress per non-zero timeout, whatever the rounding, so callers that loop
      // until a host-time deadline always get there.
      const std::uint64_t deadline =
          timeout_us == 0 ? sim_.now_us() : std::max(device_us_at(deadline_ns), sim_.now_us() + 1);
      const std::uint64_t step = std::max<std::uint32_t>(1, sim_.options().main_loop_period_us);
      while (sim_.host_readable() == 0 && sim_.now_us() < deadline)
        sim_.advance_to(std::min(deadline, sim_.now_us() + step));
    } else {
      const std::int64_t deadline_ns =
          host_monotonic_ns() + static_cast<std::int64_t>(timeout_us) * 1000;
      for (;;) {
        sim_.advance_to(device_us_at(host_monotonic_ns()));
        if (sim_.host_readable() != 0 || host_monotonic_ns() >= deadline_ns) break;
        std::this_thread::sleep_for(microseconds(200));
      }
    }
    return sim_.host_read(out, cap);
  }

  std::int64_t now_ns() const override {
    if (clock_ == SimClock::kVirtual)
      return epoch_ns_ + std::llround(static_cast<double>(sim_.now_us()) * 1000.0 / rate_);
    return host_monotonic_ns();
  }
  std::string describe() const override {
    return clock_ == SimClock::kVirtual ? "sim (virtual clock)" : "sim (real-time clock)";
  }
  Simulator& simulator() { return sim_; }

 private:
  // Firmware time (µs) at host time `host_ns`: the device clock runs `rate_` times the host's.
  std::uint64_t device_us_at(std::int64_t host_ns) const {
    const double us = static_cast<double>(host_ns - epoch_ns_) * rate_ / 1000.0;
    return us <= 0 ? 0 : static_cast<std::uint64_t>(us);
  }

  Simulator sim_;
  SimClock clock_;
  std::int64_t epoch_ns_;
  double rate_;
};

const char* field_name(std::uint8_t field) {
  switch (static_cast<ConfigField>(field)) {
    case ConfigField::kPeriod:
      return "period_us";
    case ConfigField::kPulseWidth:
      return "pulse_width_us";
    case ConfigField::kLinesMask:
      return "lines_mask";
    case ConfigField::kAdcChannelsMask:
      return "adc_channels_mask";
    case ConfigField::kHeartbeatPeriod:
      return "heartbeat_period_ms";
    case ConfigField::kNone:
      break;
  }
  return "unknown field";
}

}  // namespace

std::int64_t host_monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

Status OpenOptions::validate() const {
  if (command_timeout.count() <= 0) return invalid_argument("command_timeout must be positive");
  if (device == "sim") {
    if (sim.num_trigger_lines == 0 || sim.num_trigger_lines > 8)
      return invalid_argument("sim.num_trigger_lines must be 1..8");
    if (sim.num_adc_channels > 8) return invalid_argument("sim.num_adc_channels must be 0..8");
    if (sim.adc_bits == 0 || sim.adc_bits > 16)
      return invalid_argument("sim.adc_bits must be 1..16");
    if (!(sim.adc_reference_v > 0)) return invalid_argument("sim.adc_reference_v must be > 0");
    if (!(sim.adc_noise_v >= 0)) return invalid_argument("sim.adc_noise_v must be >= 0");
    if (!(std::abs(sim.clock_drift_ppm) <= 10'000))
      return invalid_argument("sim.clock_drift_ppm must be within +-10000");
    if (sim.main_loop_period_us == 0)
      return invalid_argument("sim.main_loop_period_us must be > 0");
    return {};
  }
  return parse_usb_spec(device).status();
}

Status TriggerConfig::validate(const HelloReply* info) const {
  if (period_us < kMinPeriodUs)
    return invalid_argument("trigger period_us " + std::to_string(period_us) + " is below the " +
                            std::to_string(kMinPeriodUs) + " µs minimum");
  if (pulse_width_us == 0 || pulse_width_us >= period_us)
    return invalid_argument("trigger pulse_width_us " + std::to_string(pulse_width_us) +
                            " must be in 1.." + std::to_string(period_us - 1) +
                            " (below period_us)");
  if (lines_mask == 0) return invalid_argument("trigger lines_mask selects no line");
  if (heartbeat_period_ms != 0 && heartbeat_period_ms < kMinHeartbeatPeriodMs)
    return invalid_argument("heartbeat_period_ms " + std::to_string(heartbeat_period_ms) +
                            " is below the " + std::to_string(kMinHeartbeatPeriodMs) +
                            " ms minimum");
  if (info != nullptr) {
    if (info->num_trigger_lines < 8 && (lines_mask >> info->num_trigger_lines) != 0)
      return invalid_argument("trigger lines_mask " + std::to_string(lines_mask) +
                              " names lines the device lacks (it has " +
                              std::to_string(info->num_trigger_lines) + ")");
    if (info->num_adc_channels < 8 && (adc_channels_mask >> info->num_adc_channels) != 0)
      return invalid_argument("adc_channels_mask names channels the device lacks (it has " +
                              std::to_string(info->num_adc_channels) + ")");
  }
  return {};
}

std::string DeviceErrorEvent::message() const {
  std::string text = to_string(report.code);
  const std::string detail = std::to_string(report.detail);
  switch (report.code) {
    case ErrorCode::kOverrun:
      return text + ": " + detail + " events dropped";
    case ErrorCode::kLateEdge:
      return text + ": " + detail + " µs after schedule";
    case ErrorCode::kHostFrameBad:
      return text + ": " + to_string(static_cast<DecodeError>(report.detail));
    case ErrorCode::kTxOverflow:
      return text + ": " + detail + " frames discarded";
    case ErrorCode::kAdcTimeout:
      return text + ": " + detail + " conversions abandoned";
  }
  return text + " (" + detail + ")";
}

Result<std::unique_ptr<FirmwareDevice>> FirmwareDevice::open(const OpenOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  if (options.device == "sim") {
    auto sim = std::make_unique<SimTransport>(options.sim, options.sim_clock);
    Simulator* simulator = &sim->simulator();
    std::unique_ptr<FirmwareDevice> dev(new FirmwareDevice());
    dev->simulator_ = simulator;
    dev->transport_ = std::move(sim);
    dev->options_ = options;
    HC_RETURN_IF_ERROR(dev->handshake());
    return dev;
  }
  HC_ASSIGN_OR_RETURN(std::unique_ptr<Transport> usb, open_usb_transport(options.device));
  return open(std::move(usb), options);
}

Result<std::unique_ptr<FirmwareDevice>> FirmwareDevice::open(std::unique_ptr<Transport> transport,
                                                             const OpenOptions& options) {
  if (!transport) return invalid_argument("null transport");
  if (options.command_timeout.count() <= 0)
    return invalid_argument("command_timeout must be positive");
  std::unique_ptr<FirmwareDevice> dev(new FirmwareDevice());
  dev->transport_ = std::move(transport);
  dev->options_ = options;
  HC_RETURN_IF_ERROR(dev->handshake());
  return dev;
}

Status FirmwareDevice::handshake() {
  open_ = true;
  info_.transport = transport_->describe();
  // A lone delimiter makes the device drop any half-received frame left from an earlier session.
  const std::uint8_t flush = 0;
  HC_RETURN_IF_ERROR(transport_->write(&flush, 1));
  ++stats_.bytes_out;
  Message hello = make_message(MessageType::kHello, 0);
  hello.hello.protocol_version = kProtocolVersion;
  const Status st = command(hello, options_.command_timeout);
  if (!st.ok()) {
    open_ = false;
    return st.with_context("firmware handshake with " + info_.transport);
  }
  if (reply_->hello_reply.protocol_version != kProtocolVersion) {
    open_ = false;
    return failed_precondition("firmware at " + info_.transport + " speaks protocol version " +
                               std::to_string(reply_->hello_reply.protocol_version) +
                               ", this driver speaks " + std::to_string(kProtocolVersion));
  }
  info_.hello = reply_->hello_reply;
  return {};
}

FirmwareDevice::~FirmwareDevice() { close(); }

void FirmwareDevice::close() {
  if (!open_) return;
  open_ = false;
  // Best effort: leave the lines low if the device is still there; no wait for the Ack.
  (void)send(make_message(MessageType::kStop, 0));
  transport_.reset();
  simulator_ = nullptr;
}

Status FirmwareDevice::send(Message msg) {
  if (!transport_) return failed_precondition("firmware device is closed");
  msg.seq = next_seq_++;
  std::uint8_t frame[kMaxFrameSize];
  const std::size_t n = encode_frame(msg, frame, sizeof frame);
  if (n == 0) return internal_error("cannot encode " + std::string(to_string(msg.type)));
  HC_RETURN_IF_ERROR(transport_->write(frame, n));
  stats_.bytes_out += n;
  ++stats_.frames_out;
  return {};
}

Status FirmwareDevice::command(Message msg, microseconds timeout) {
  if (!transport_) return failed_precondition("firmware device is closed");
  awaiting_seq_ = next_seq_;
  awaiting_type_ = msg.type;
  awaiting_ = true;
  reply_.reset();
  const Status sent = send(msg);
  if (!sent.ok()) {
    awaiting_ = false;
    return sent;
  }
  const std::int64_t deadline = transport_->now_ns() + timeout.count() * 1000;
  while (!reply_) {
    const std::int64_t left_ns = deadline - transport_->now_ns();
    if (left_ns <= 0) break;
    const Status st = read_some(microseconds(std::max<std::int64_t>(1, left_ns / 1000)));
    if (!st.ok()) {
      awaiting_ = false;
      return st;
    }
  }
  awaiting_ = false;
  const std::string what = to_string(msg.type);
  if (!reply_)
    return deadline_exceeded("no answer to " + what + " from " + info_.transport + " within " +
                             std::to_string(timeout.count() / 1000) + " ms");
  if (reply_->type == MessageType::kNack) {
    const Nack& n = reply_->nack;
    std::string text = "firmware refused " + what + ": " + to_string(n.reason);
    switch (n.reason) {
      case NackReason::kInvalidConfig:
        return invalid_argument(text + " (" + field_name(n.detail) + ")");
      case NackReason::kBadVersion:
      case NackReason::kNotConfigured:
      case NackReason::kBusy:
        return failed_precondition(text);
      case NackReason::kUnexpected:
        return internal_error(text);
    }
    return internal_error(text);
  }
  return {};
}

Status FirmwareDevice::read_some(microseconds timeout) {
  std::uint8_t buf[1024];
  HC_ASSIGN_OR_RETURN(const std::size_t n, transport_->read(buf, sizeof buf, timeout));
  if (n == 0) return {};
  const std::int64_t rx_ns = transport_->now_ns();
  stats_.bytes_in += n;
  const std::uint8_t* p = buf;
  const std::uint8_t* const end = buf + n;
  Message msg;
  DecodeError err = DecodeError::kOk;
  for (;;) {
    const StreamDecoder::Result r = decoder_.next(&p, end, &msg, &err);
    if (r == StreamDecoder::Result::kNeedMore) break;
    if (r == StreamDecoder::Result::kMessage) handle(msg, rx_ns);
  }
  return {};
}

void FirmwareDevice::update_offset(std::uint64_t device_time_us, std::int64_t rx_ns) {
  const std::int64_t d = rx_ns - static_cast<std::int64_t>(device_time_us) * 1000;
  if (!have_offset_) {
    have_offset_ = true;
    window_start_ns_ = rx_ns;
    window_min_ = d;
  } else if (rx_ns - window_start_ns_ > kOffsetWindowNs) {
    prev_window_min_ = window_min_;
    have_prev_window_ = true;
    window_start_ns_ = rx_ns;
    window_min_ = d;
  } else {
    window_min_ = std::min(window_min_, d);
  }
  offset_ns_ = have_prev_window_ ? std::min(prev_window_min_, window_min_) : window_min_;
}

std::int64_t FirmwareDevice::device_to_host_ns(std::uint64_t device_time_us) const {
  return static_cast<std::int64_t>(device_time_us) * 1000 + offset_ns_;
}

void FirmwareDevice::handle(const Message& msg, std::int64_t rx_ns) {
  ++stats_.frames_in;
  if (last_device_seq_) {
    const auto gap = static_cast<std::uint16_t>(msg.seq - *last_device_seq_ - 1);
    stats_.frames_lost += gap;
  }
  last_device_seq_ = msg.seq;

  Event ev;
  switch (msg.type) {
    case MessageType::kHelloReply:
      if (awaiting_ && awaiting_type_ == MessageType::kHello) reply_ = msg;
      return;
    case MessageType::kAck:
      if (awaiting_ && msg.ack.acked_seq == awaiting_seq_) reply_ = msg;
      return;
    case MessageType::kNack:
      if (awaiting_ && msg.nack.acked_seq == awaiting_seq_) reply_ = msg;
      return;
    case MessageType::kTriggerEdge:
      update_offset(msg.edge.timestamp_us, rx_ns);
      ev.kind = Event::Kind::kTriggerEdge;
      ev.edge.edge_index = msg.edge.edge_index;
      ev.edge.device_time_us = msg.edge.timestamp_us;
      ev.edge.lines_mask = msg.edge.lines_mask;
      ev.edge.lateness_us = msg.edge.lateness_us;
      ev.edge.host_rx_ns = rx_ns;
      ev.edge.host_time_ns = device_to_host_ns(msg.edge.timestamp_us);
      break;
    case MessageType::kAdcSample:
      update_offset(msg.sample.timestamp_us, rx_ns);
      ev.kind = Event::Kind::kAdcSample;
      ev.sample.edge_index = msg.sample.edge_index;
      ev.sample.channel = msg.sample.channel;
      ev.sample.raw = msg.sample.raw;
      ev.sample.device_time_us = msg.sample.timestamp_us;
      ev.sample.host_rx_ns = rx_ns;
      ev.sample.host_time_ns = device_to_host_ns(msg.sample.timestamp_us);
      break;
    case MessageType::kHeartbeat:
      update_offset(msg.heartbeat.uptime_us, rx_ns);
      ev.kind = Event::Kind::kHeartbeat;
      ev.heartbeat.heartbeat = msg.heartbeat;
      ev.heartbeat.host_rx_ns = rx_ns;
      last_heartbeat_ = ev.heartbeat;
      break;
    case MessageType::kError:
      ++stats_.device_errors;
      ev.kind = Event::Kind::kError;
      ev.error.report = msg.error;
      ev.error.host_rx_ns = rx_ns;
      break;
    default:
      return;  // a host->device type from the device: ignored
  }
  pending_.push_back(ev);
}

Result<std::size_t> FirmwareDevice::poll(std::vector<Event>& out, microseconds timeout) {
  if (!transport_) return failed_precondition("firmware device is closed");
  HC_RETURN_IF_ERROR(read_some(microseconds(0)));
  const std::int64_t deadline = transport_->now_ns() + timeout.count() * 1000;
  while (pending_.empty()) {
    const std::int64_t left_ns = deadline - transport_->now_ns();
    if (left_ns <= 0) break;
    HC_RETURN_IF_ERROR(read_some(microseconds(std::max<std::int64_t>(1, left_ns / 1000))));
  }
  const std::size_t n = pending_.size();
  out.insert(out.end(), pending_.begin(), pending_.end());
  pending_.clear();
  return n;
}

Status FirmwareDevice::configure_trigger(const TriggerConfig& config) {
  HC_RETURN_IF_ERROR(config.validate(&info_.hello));
  Message m = make_message(MessageType::kConfigureTrigger, 0);
  m.configure.period_us = config.period_us;
  m.configure.pulse_width_us = config.pulse_width_us;
  m.configure.lines_mask = config.lines_mask;
  m.configure.adc_channels_mask = config.adc_channels_mask;
  m.configure.count = config.count;
  m.configure.heartbeat_period_ms = config.heartbeat_period_ms;
  return command(m, options_.command_timeout);
}

Status FirmwareDevice::start(std::uint32_t start_delay_us) {
  Message m = make_message(MessageType::kStart, 0);
  m.start.start_delay_us = start_delay_us;
  return command(m, options_.command_timeout);
}

Status FirmwareDevice::stop() {
  return command(make_message(MessageType::kStop, 0), options_.command_timeout);
}

LinkStats FirmwareDevice::link_stats() const {
  LinkStats s = stats_;
  s.frames_corrupt = decoder_.frames_bad();
  s.bytes_discarded = decoder_.bytes_discarded();
  return s;
}

}  // namespace hc::fw
