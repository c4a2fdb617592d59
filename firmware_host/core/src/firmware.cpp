#include "firmware_host/core/firmware.h"

namespace hc::fw {
namespace {

std::uint16_t saturate16(std::uint64_t v) {
  return v > 0xFFFFu ? std::uint16_t{0xFFFF} : static_cast<std::uint16_t>(v);
}

std::uint8_t lowest_bit(std::uint8_t mask) {
  std::uint8_t bit = 0;
  while (((mask >> bit) & 1u) == 0) ++bit;
  return bit;
}

bool mask_fits(std::uint8_t mask, std::uint8_t count) { return count >= 8 || (mask >> count) == 0; }

}  // namespace

Firmware::Firmware(Hal& hal, const FirmwareInfo& info) : hal_(hal), info_(info) {}

// ---- interrupt context --------------------------------------------------------------------------

void Firmware::push_event(const CoreEvent& e) {
  if (!ring_.push(e)) dropped_.fetch_add(1, std::memory_order_relaxed);
}

void Firmware::on_timer() {
  if (!running_.load(std::memory_order_acquire)) return;
  if (!high_phase_) {
    hal_.gpio_set(config_.lines_mask);
    const std::uint64_t t = hal_.now_us();
    const std::uint64_t late = t > scheduled_us_ ? t - scheduled_us_ : 0;
    if (late > kLateEdgeThresholdUs) {
      late_edges_.fetch_add(1, std::memory_order_relaxed);
      const std::uint32_t late32 =
          late > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<std::uint32_t>(late);
      if (late32 > max_lateness_us_.load(std::memory_order_relaxed))
        max_lateness_us_.store(late32, std::memory_order_relaxed);
    }
    CoreEvent e;
    e.kind = CoreEvent::kEdge;
    e.lines_or_channel = config_.lines_mask;
    e.lateness_or_raw = saturate16(late);
    e.edge_index = edge_index_;
    e.timestamp_us = t;
    push_event(e);
    edges_emitted_.store(edge_index_ + 1, std::memory_order_relaxed);
    if (config_.adc_channels_mask != 0) {
      if (adc_busy_) adc_timeouts_.fetch_add(1, std::memory_order_relaxed);  // abandoned
      adc_edge_index_ = edge_index_;
      adc_remaining_mask_ = config_.adc_channels_mask;
      start_next_adc();
    }
    high_phase_ = true;
    scheduled_us_ += config_.pulse_width_us;
    hal_.timer_arm(scheduled_us_);
    return;
  }
  hal_.gpio_clear(config_.lines_mask);
  high_phase_ = false;
  ++edge_index_;
  if (config_.count != 0 && edge_index_ >= config_.count) {
    running_.store(false, std::memory_order_release);
    state_.store(SequencerState::kDone, std::memory_order_release);
    return;
  }
  scheduled_us_ = t0_us_ + static_cast<std::uint64_t>(edge_index_) * config_.period_us;
  hal_.timer_arm(scheduled_us_);
}

void Firmware::start_next_adc() {
  if (adc_remaining_mask_ == 0) {
    adc_busy_ = false;
    return;
  }
  adc_channel_ = lowest_bit(adc_remaining_mask_);
  adc_remaining_mask_ = static_cast<std::uint8_t>(adc_remaining_mask_ & ~(1u << adc_channel_));
  adc_busy_ = true;
  adc_start_us_ = hal_.now_us();
  hal_.adc_start(adc_channel_);
}

void Firmware::on_adc_complete() {
  if (!adc_busy_) return;  // spurious, or a conversion abandoned by stop
  CoreEvent e;
  e.kind = CoreEvent::kSample;
  e.lines_or_channel = adc_channel_;
  e.lateness_or_raw = hal_.adc_read();
  e.edge_index = adc_edge_index_;
  e.timestamp_us = adc_start_us_;
  push_event(e);
  start_next_adc();
}

// ---- main loop ----------------------------------------------------------------------------------

void Firmware::queue_control(const Message& msg) {
  if (control_count_ == kControlQueueSize) {
    ++control_dropped_;
    return;
  }
  control_[(control_head_ + control_count_) % kControlQueueSize] = msg;
  ++control_count_;
}

void Firmware::queue_error(ErrorCode code, std::uint32_t detail) {
  Message m = make_message(MessageType::kError, 0);
  m.error.code = code;
  m.error.detail = detail;
  m.error.timestamp_us = hal_.now_us();
  queue_control(m);
}

void Firmware::ack(const Message& cmd) {
  Message m = make_message(MessageType::kAck, 0);
  m.ack.acked_seq = cmd.seq;
  m.ack.acked_type = cmd.type;
  queue_control(m);
}

void Firmware::nack(const Message& cmd, NackReason reason, std::uint8_t detail) {
  Message m = make_message(MessageType::kNack, 0);
  m.nack.acked_seq = cmd.seq;
  m.nack.acked_type = cmd.type;
  m.nack.reason = reason;
  m.nack.detail = detail;
  queue_control(m);
}

ConfigField Firmware::check_config(const ConfigureTrigger& c) const {
  if (c.period_us < kFirmwareMinPeriodUs) return ConfigField::kPeriod;
  if (c.pulse_width_us == 0 || c.pulse_width_us >= c.period_us) return ConfigField::kPulseWidth;
  if (c.lines_mask == 0 || !mask_fits(c.lines_mask, info_.num_trigger_lines))
    return ConfigField::kLinesMask;
  if (!mask_fits(c.adc_channels_mask, info_.num_adc_channels)) return ConfigField::kAdcChannelsMask;
  if (c.heartbeat_period_ms != 0 && c.heartbeat_period_ms < kFirmwareMinHeartbeatMs)
    return ConfigField::kHeartbeatPeriod;
  return ConfigField::kNone;
}

void Firmware::stop_sequencer() {
  hal_.enter_critical();
  running_.store(false, std::memory_order_release);
  hal_.timer_disarm();
  if (configured_) hal_.gpio_clear(config_.lines_mask);
  high_phase_ = false;
  adc_busy_ = false;
  adc_remaining_mask_ = 0;
  state_.store(configured_ ? SequencerState::kConfigured : SequencerState::kIdle,
               std::memory_order_release);
  hal_.exit_critical();
}

void Firmware::handle_command(const Message& msg) {
  switch (msg.type) {
    case MessageType::kHello: {
      if (msg.hello.protocol_version != kProtocolVersion) {
        nack(msg, NackReason::kBadVersion);
        return;
      }
      Message r = make_message(MessageType::kHelloReply, 0);
      r.hello_reply.protocol_version = kProtocolVersion;
      r.hello_reply.firmware_major = info_.firmware_major;
      r.hello_reply.firmware_minor = info_.firmware_minor;
      r.hello_reply.firmware_patch = info_.firmware_patch;
      r.hello_reply.num_trigger_lines = info_.num_trigger_lines;
      r.hello_reply.num_adc_channels = info_.num_adc_channels;
      r.hello_reply.adc_bits = info_.adc_bits;
      r.hello_reply.event_capacity = static_cast<std::uint16_t>(kEventCapacity);
      queue_control(r);
      link_up_ = true;
      next_heartbeat_us_ = hal_.now_us() + std::uint64_t{heartbeat_ms_} * 1000u;
      return;
    }
    case MessageType::kConfigureTrigger: {
      if (running_.load(std::memory_order_acquire)) {
        nack(msg, NackReason::kBusy);
        return;
      }
      const ConfigField bad = check_config(msg.configure);
      if (bad != ConfigField::kNone) {
        nack(msg, NackReason::kInvalidConfig, static_cast<std::uint8_t>(bad));
        return;
      }
      hal_.enter_critical();
      config_ = msg.configure;
      configured_ = true;
      state_.store(SequencerState::kConfigured, std::memory_order_release);
      hal_.exit_critical();
      heartbeat_ms_ = msg.configure.heartbeat_period_ms != 0 ? msg.configure.heartbeat_period_ms
                                                             : kDefaultHeartbeatMs;
      next_heartbeat_us_ = hal_.now_us() + std::uint64_t{heartbeat_ms_} * 1000u;
      ack(msg);
      return;
    }
    case MessageType::kStart: {
      if (!configured_) {
        nack(msg, NackReason::kNotConfigured);
        return;
      }
      if (running_.load(std::memory_order_acquire)) {
        nack(msg, NackReason::kBusy);
        return;
      }
      const std::uint32_t delay =
          msg.start.start_delay_us > kMinStartDelayUs ? msg.start.start_delay_us : kMinStartDelayUs;
      hal_.enter_critical();
      edge_index_ = 0;
      edges_emitted_.store(0, std::memory_order_relaxed);
      high_phase_ = false;
      t0_us_ = hal_.now_us() + delay;
      scheduled_us_ = t0_us_;
      running_.store(true, std::memory_order_release);
      state_.store(SequencerState::kRunning, std::memory_order_release);
      hal_.timer_arm(t0_us_);
      hal_.exit_critical();
      ack(msg);
      return;
    }
    case MessageType::kStop:
      stop_sequencer();
      ack(msg);
      return;
    default:
      nack(msg, NackReason::kUnexpected);
      return;
  }
}

bool Firmware::next_frame() {
  Message m;
  if (control_count_ != 0) {
    m = control_[control_head_];
    control_head_ = (control_head_ + 1) % kControlQueueSize;
    --control_count_;
  } else {
    CoreEvent e;
    if (!ring_.pop(&e)) return false;
    if (e.kind == CoreEvent::kEdge) {
      m.type = MessageType::kTriggerEdge;
      m.edge.edge_index = e.edge_index;
      m.edge.timestamp_us = e.timestamp_us;
      m.edge.lines_mask = e.lines_or_channel;
      m.edge.lateness_us = e.lateness_or_raw;
    } else {
      m.type = MessageType::kAdcSample;
      m.sample.edge_index = e.edge_index;
      m.sample.timestamp_us = e.timestamp_us;
      m.sample.channel = e.lines_or_channel;
      m.sample.raw = e.lateness_or_raw;
    }
  }
  m.seq = tx_seq_++;
  tx_len_ = encode_frame(m, tx_buf_, sizeof tx_buf_);
  tx_off_ = 0;
  ++tx_frames_;
  return tx_len_ != 0;
}

void Firmware::transmit() {
  for (;;) {
    if (tx_off_ == tx_len_ && !next_frame()) return;
    const std::size_t written = hal_.usb_write(tx_buf_ + tx_off_, tx_len_ - tx_off_);
    if (written == 0) return;  // endpoint busy: resume on the next poll
    tx_off_ += written;
  }
}

void Firmware::poll() {
  // Host commands (bounded per iteration so a flooding host cannot starve transmission).
  constexpr int kMaxReadsPerPoll = 4;
  for (int i = 0; i < kMaxReadsPerPoll; ++i) {
    std::uint8_t rx[64];
    const std::size_t n = hal_.usb_read(rx, sizeof rx);
    if (n == 0) break;
    const std::uint8_t* p = rx;
    const std::uint8_t* const end = rx + n;
    Message msg;
    DecodeError err = DecodeError::kOk;
    for (;;) {
      const StreamDecoder::Result r = decoder_.next(&p, end, &msg, &err);
      if (r == StreamDecoder::Result::kNeedMore) break;
      if (r == StreamDecoder::Result::kMessage)
        handle_command(msg);
      else
        queue_error(ErrorCode::kHostFrameBad, static_cast<std::uint32_t>(err));
    }
  }

  // Faults raised in interrupt context, reported as deltas once there is room to report them.
  const auto report = [this](ErrorCode code, std::uint32_t now_count, std::uint32_t& reported,
                             std::uint32_t detail) {
    if (now_count == reported || control_count_ == kControlQueueSize) return;
    queue_error(code, detail);
    reported = now_count;
  };
  const std::uint32_t dropped = dropped_.load(std::memory_order_relaxed);
  report(ErrorCode::kOverrun, dropped, reported_dropped_, dropped - reported_dropped_);
  const std::uint32_t late = late_edges_.load(std::memory_order_relaxed);
  if (late != reported_late_ && control_count_ != kControlQueueSize)
    report(ErrorCode::kLateEdge, late, reported_late_,
           max_lateness_us_.exchange(0, std::memory_order_relaxed));
  const std::uint32_t adc_timeouts = adc_timeouts_.load(std::memory_order_relaxed);
  report(ErrorCode::kAdcTimeout, adc_timeouts, reported_adc_timeouts_,
         adc_timeouts - reported_adc_timeouts_);
  report(ErrorCode::kTxOverflow, control_dropped_, reported_control_dropped_,
         control_dropped_ - reported_control_dropped_);

  const std::uint64_t now = hal_.now_us();
  if (link_up_ && now >= next_heartbeat_us_ && control_count_ != kControlQueueSize) {
    Message hb = make_message(MessageType::kHeartbeat, 0);
    hb.heartbeat.uptime_us = now;
    hb.heartbeat.buffer_fill = static_cast<std::uint16_t>(ring_.size());
    hb.heartbeat.buffer_capacity = static_cast<std::uint16_t>(kEventCapacity);
    hb.heartbeat.dropped_events = dropped_.load(std::memory_order_relaxed);
    hb.heartbeat.edges_emitted = edges_emitted_.load(std::memory_order_relaxed);
    hb.heartbeat.state = state_.load(std::memory_order_acquire);
    queue_control(hb);
    next_heartbeat_us_ = now + std::uint64_t{heartbeat_ms_} * 1000u;
  }

  transmit();
}

}  // namespace hc::fw
