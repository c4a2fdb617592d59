#include "firmware_host/simulator/simulator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "firmware_host/core/firmware.h"
#include "firmware_host/core/hal.h"

namespace hc::fw {

// Virtual peripherals behind the core's Hal. Single-threaded: interrupts are delivered by
// Simulator::advance_to between main-loop passes, so the critical sections need no masking.
class VirtualHal final : public Hal {
 public:
  explicit VirtualHal(const SimulatorOptions& options)
      : options_(options), rng_(options.seed), noise_(0.0, 1.0) {}

  std::uint64_t now_us() override { return now_; }
  void timer_arm(std::uint64_t at_us) override { armed_ = at_us; }
  void timer_disarm() override { armed_ = kNever; }
  void gpio_set(std::uint8_t mask) override { drive(mask, true); }
  void gpio_clear(std::uint8_t mask) override { drive(mask, false); }
  void adc_start(std::uint8_t channel) override {
    double v = options_.adc_source ? options_.adc_source(channel, now_) : 0.0;
    if (options_.adc_noise_v > 0) v += options_.adc_noise_v * noise_(rng_);
    v = std::clamp(v, 0.0, options_.adc_reference_v);
    const double full_scale = std::ldexp(1.0, options_.adc_bits) - 1.0;
    adc_value_ = static_cast<std::uint16_t>(std::lround(v / options_.adc_reference_v * full_scale));
    adc_done_ = adc_stuck_ ? kNever : now_ + options_.adc_conversion_us;
    conversions_.push_back({now_, channel, adc_value_});
  }
  std::uint16_t adc_read() override { return adc_value_; }
  std::size_t usb_write(const std::uint8_t* data, std::size_t size) override {
    if (stalled_) return 0;
    const std::size_t n =
        std::min(size, options_.usb_in_capacity - std::min(options_.usb_in_capacity, in_.size()));
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t offset = in_sent_++;
      if (drops_.count(offset) != 0) continue;
      std::uint8_t b = data[i];
      if (auto it = corruptions_.find(offset); it != corruptions_.end()) b ^= it->second;
      in_.push_back(b);
    }
    return n;
  }
  std::size_t usb_read(std::uint8_t* out, std::size_t cap) override {
    std::size_t n = 0;
    while (n < cap && !out_.empty()) {
      out[n++] = out_.front();
      out_.pop_front();
    }
    return n;
  }
  void enter_critical() override {}
  void exit_critical() override {}

  static constexpr std::uint64_t kNever = std::numeric_limits<std::uint64_t>::max();

  const SimulatorOptions& options_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_;
  std::uint64_t now_ = 0;
  std::uint64_t armed_ = kNever;
  std::uint64_t adc_done_ = kNever;
  std::uint64_t next_loop_ = 0;
  std::uint16_t adc_value_ = 0;
  std::uint8_t line_state_ = 0;
  std::vector<GpioEdge> edges_;
  std::vector<Simulator::AdcConversion> conversions_;
  std::deque<std::uint8_t> in_;   // device -> host
  std::deque<std::uint8_t> out_;  // host -> device
  std::uint64_t in_sent_ = 0;
  bool stalled_ = false;
  bool adc_stuck_ = false;
  std::map<std::uint64_t, std::uint8_t> corruptions_;
  std::set<std::uint64_t> drops_;

 private:
  void drive(std::uint8_t mask, bool high) {
    for (std::uint8_t line = 0; line < 8; ++line) {
      const std::uint8_t bit = static_cast<std::uint8_t>(1u << line);
      if ((mask & bit) == 0 || line >= options_.num_trigger_lines) continue;
      const bool was_high = (line_state_ & bit) != 0;
      if (was_high == high) continue;
      line_state_ = static_cast<std::uint8_t>(high ? (line_state_ | bit) : (line_state_ & ~bit));
      edges_.push_back({now_, line, high});
    }
  }
};

namespace {

FirmwareInfo info_from(const SimulatorOptions& o) {
  FirmwareInfo info;
  info.num_trigger_lines = o.num_trigger_lines;
  info.num_adc_channels = o.num_adc_channels;
  info.adc_bits = o.adc_bits;
  return info;
}

}  // namespace

Simulator::Simulator(SimulatorOptions options)
    : options_(std::move(options)),
      hal_(std::make_unique<VirtualHal>(options_)),
      firmware_(std::make_unique<Firmware>(*hal_, info_from(options_))) {
  if (options_.main_loop_period_us == 0) options_.main_loop_period_us = 1;
}

Simulator::~Simulator() = default;

std::uint64_t Simulator::now_us() const { return hal_->now_; }

void Simulator::advance_to(std::uint64_t t_us) {
  VirtualHal& h = *hal_;
  for (;;) {
    const std::uint64_t t_timer = h.armed_ == VirtualHal::kNever
                                      ? VirtualHal::kNever
                                      : std::max(h.armed_, h.now_) + options_.isr_latency_us;
    const std::uint64_t t_adc = h.adc_done_;
    const std::uint64_t t_loop = std::max(h.next_loop_, h.now_);
    const std::uint64_t t = std::min({t_timer, t_adc, t_loop});
    if (t > t_us) break;
    h.now_ = t;
    if (t == t_timer) {  // interrupts before the main loop on a tie, timer first
      h.armed_ = VirtualHal::kNever;
      firmware_->on_timer();
    } else if (t == t_adc) {
      h.adc_done_ = VirtualHal::kNever;
      firmware_->on_adc_complete();
    } else {
      firmware_->poll();
      h.next_loop_ = t + options_.main_loop_period_us;
    }
  }
  if (t_us > h.now_) h.now_ = t_us;
}

void Simulator::host_write(const std::uint8_t* data, std::size_t size) {
  hal_->out_.insert(hal_->out_.end(), data, data + size);
}

std::size_t Simulator::host_read(std::uint8_t* out, std::size_t cap) {
  std::size_t n = 0;
  while (n < cap && !hal_->in_.empty()) {
    out[n++] = hal_->in_.front();
    hal_->in_.pop_front();
  }
  return n;
}

std::size_t Simulator::host_readable() const { return hal_->in_.size(); }

void Simulator::corrupt_in_byte(std::uint64_t offset, std::uint8_t mask) {
  hal_->corruptions_[offset] = mask;
}

void Simulator::drop_in_byte(std::uint64_t offset) { hal_->drops_.insert(offset); }

std::uint64_t Simulator::in_bytes_sent() const { return hal_->in_sent_; }

void Simulator::set_usb_stalled(bool stalled) { hal_->stalled_ = stalled; }

void Simulator::set_adc_stuck(bool stuck) { hal_->adc_stuck_ = stuck; }

const std::vector<GpioEdge>& Simulator::gpio_edges() const { return hal_->edges_; }

const std::vector<Simulator::AdcConversion>& Simulator::adc_conversions() const {
  return hal_->conversions_;
}

Firmware& Simulator::firmware() { return *firmware_; }

}  // namespace hc::fw
