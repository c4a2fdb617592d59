// The portable firmware core: a trigger sequencer with µs timing, ADC sampling synchronised to each
// rising trigger edge, an SPSC event ring between interrupts and the main loop, host command
// handling over the wire protocol, heartbeats and error reports. No heap, no OS, no exceptions, no
// RTTI, no std containers: every buffer is a fixed-size member, so a Firmware object can live in
// .bss.
//
// Execution model (as on a microcontroller):
//   * on_timer()        — timer-compare ISR: drives the lines, timestamps edges, starts the ADC;
//   * on_adc_complete() — ADC ISR: reads the conversion, queues the sample, starts the next
//   channel;
//   * poll()            — main loop: reads host commands, transmits queued events and replies,
//                         sends heartbeats and error reports. Touches sequencer state only inside
//                         Hal::enter_critical()/exit_critical().
// Timing: rising edge k is scheduled at t0 + k * period_us (absolute, so timer latency never
// accumulates); the falling edge at rise_k + pulse_width_us. An edge that fires more than
// kLateEdgeThresholdUs after its schedule is reported (ErrorCode::kLateEdge).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "firmware_host/core/hal.h"
#include "firmware_host/core/spsc_ring.h"
#include "firmware_host/protocol/messages.h"

namespace hc::fw {

struct FirmwareInfo {
  std::uint8_t firmware_major = 1;
  std::uint8_t firmware_minor = 0;
  std::uint8_t firmware_patch = 0;
  std::uint8_t num_trigger_lines = 4;  // at most 8
  std::uint8_t num_adc_channels = 4;   // at most 8
  std::uint8_t adc_bits = 12;
};

inline constexpr std::size_t kEventCapacity = 256;  // ring slots (16 bytes each)
inline constexpr std::uint32_t kFirmwareMinPeriodUs = 100;
inline constexpr std::uint16_t kFirmwareMinHeartbeatMs = 10;
inline constexpr std::uint16_t kDefaultHeartbeatMs = 100;
inline constexpr std::uint32_t kMinStartDelayUs = 100;  // lets the Ack leave before the first edge
// Harp devices timestamp to ±42 µs (RIG_PROTOCOL_FACTS.md); we flag edges later than this.
inline constexpr std::uint32_t kLateEdgeThresholdUs = 42;
inline constexpr std::size_t kControlQueueSize = 8;

// One ring slot: a trigger edge or an ADC sample, as produced in interrupt context.
struct CoreEvent {
  enum Kind : std::uint8_t { kEdge = 0, kSample = 1 };
  Kind kind = kEdge;
  std::uint8_t lines_or_channel = 0;
  std::uint16_t lateness_or_raw = 0;
  std::uint32_t edge_index = 0;
  std::uint64_t timestamp_us = 0;
};

class Firmware {
 public:
  Firmware(Hal& hal, const FirmwareInfo& info);

  // ISR entry points.
  void on_timer();
  void on_adc_complete();
  // One main-loop iteration.
  void poll();

  // Introspection (tests, debugging).
  SequencerState state() const { return state_.load(std::memory_order_acquire); }
  std::uint32_t dropped_events() const { return dropped_.load(std::memory_order_relaxed); }
  std::size_t buffer_fill() const { return ring_.size(); }
  std::uint32_t edges_emitted() const { return edges_emitted_.load(std::memory_order_relaxed); }
  std::uint32_t tx_frames() const { return tx_frames_; }
  std::uint32_t host_frames_bad() const { return decoder_.frames_bad(); }
  const ConfigureTrigger& config() const { return config_; }

 private:
  void handle_command(const Message& msg);
  void queue_control(const Message& msg);
  void queue_error(ErrorCode code, std::uint32_t detail);
  void nack(const Message& cmd, NackReason reason, std::uint8_t detail = 0);
  void ack(const Message& cmd);
  ConfigField check_config(const ConfigureTrigger& c) const;
  void stop_sequencer();
  bool next_frame();  // fills tx_ with the next frame to send; false when nothing is queued
  void transmit();
  void push_event(const CoreEvent& e);
  void start_next_adc();

  Hal& hal_;
  FirmwareInfo info_;

  // Sequencer (ISR-owned while running_).
  ConfigureTrigger config_;
  bool configured_ = false;
  std::atomic<bool> running_{false};
  std::atomic<SequencerState> state_{SequencerState::kIdle};
  bool high_phase_ = false;  // lines are high, next compare is the falling edge
  std::uint64_t t0_us_ = 0;
  std::uint64_t scheduled_us_ = 0;
  std::uint32_t edge_index_ = 0;  // index of the next rising edge
  std::atomic<std::uint32_t> edges_emitted_{0};

  // ADC (ISR-owned).
  bool adc_busy_ = false;
  std::uint8_t adc_channel_ = 0;
  std::uint8_t adc_remaining_mask_ = 0;
  std::uint32_t adc_edge_index_ = 0;
  std::uint64_t adc_start_us_ = 0;
  std::atomic<std::uint32_t> adc_timeouts_{0};

  // ISR -> main loop.
  SpscRing<CoreEvent, kEventCapacity> ring_;
  std::atomic<std::uint32_t> dropped_{0};
  std::atomic<std::uint32_t> late_edges_{0};
  std::atomic<std::uint32_t> max_lateness_us_{0};

  // Main loop only.
  StreamDecoder decoder_;
  bool link_up_ = false;  // after the first Hello: heartbeats flow
  std::uint16_t tx_seq_ = 0;
  std::uint32_t tx_frames_ = 0;
  std::uint8_t tx_buf_[kMaxFrameSize] = {};
  std::size_t tx_len_ = 0;
  std::size_t tx_off_ = 0;
  Message control_[kControlQueueSize];
  std::size_t control_head_ = 0;
  std::size_t control_count_ = 0;
  std::uint32_t control_dropped_ = 0;
  std::uint32_t reported_dropped_ = 0;
  std::uint32_t reported_late_ = 0;
  std::uint32_t reported_adc_timeouts_ = 0;
  std::uint32_t reported_control_dropped_ = 0;
  std::uint64_t next_heartbeat_us_ = 0;
  std::uint16_t heartbeat_ms_ = kDefaultHeartbeatMs;
};

}  // namespace hc::fw
