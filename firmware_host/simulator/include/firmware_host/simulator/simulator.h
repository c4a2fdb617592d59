// The firmware simulator: runs the SAME portable core (firmware_host/core) against virtual
// peripherals — a virtual µs clock, virtual GPIO lines that record every edge, a virtual ADC fed by
// a callback (e.g. a force source through an FSR divider) with seeded Gaussian noise, and a virtual
// USB link (two byte queues) with injectable faults. Deterministic: the same options and the same
// calls give the same bytes. Host-only code (uses the heap and std), unlike the core.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <random>
#include <vector>

namespace hc::fw {

class Firmware;
class VirtualHal;

// Voltage on an ADC input at firmware time t_us (volts, clamped to [0, adc_reference_v]).
using AdcSource = std::function<double(std::uint8_t channel, std::uint64_t t_us)>;

struct SimulatorOptions {
  std::uint8_t num_trigger_lines = 4;
  std::uint8_t num_adc_channels = 4;
  std::uint8_t adc_bits = 12;
  double adc_reference_v = 3.3;
  std::uint32_t adc_conversion_us = 5;  // start -> conversion-complete interrupt
  double adc_noise_v = 0.0;             // Gaussian noise standard deviation, volts
  std::uint64_t seed = 1;
  AdcSource adc_source;                     // empty = 0 V on every channel
  std::uint32_t main_loop_period_us = 100;  // how often the core's poll() runs
  std::uint32_t isr_latency_us = 0;         // added to every timer interrupt (late-edge testing)
  std::size_t usb_in_capacity = 1 << 20;    // bytes the device->host queue holds before stalling
  // The device crystal's frequency error: the firmware clock advances (1 + ppm * 1e-6) µs per host
  // µs. Applied by the driver's simulator transport when it maps virtual device time to host time.
  double clock_drift_ppm = 0.0;
};

// One recorded GPIO transition.
struct GpioEdge {
  std::uint64_t t_us = 0;
  std::uint8_t line = 0;
  bool high = false;
};

class Simulator {
 public:
  explicit Simulator(SimulatorOptions options = {});
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  // Runs the core (interrupts and main loop) until virtual time t_us (never backwards).
  void advance_to(std::uint64_t t_us);
  void advance_by(std::uint64_t dt_us) { advance_to(now_us() + dt_us); }
  std::uint64_t now_us() const;

  // Virtual USB: host writes to the device's bulk OUT, reads from its bulk IN.
  void host_write(const std::uint8_t* data, std::size_t size);
  std::size_t host_read(std::uint8_t* out, std::size_t cap);
  std::size_t host_readable() const;

  // Link faults, applied to device->host bytes: the byte at stream offset `offset` (counted from
  // the first byte the device ever sent) is XORed with `mask` / dropped.
  void corrupt_in_byte(std::uint64_t offset, std::uint8_t mask = 0xFF);
  void drop_in_byte(std::uint64_t offset);
  std::uint64_t in_bytes_sent() const;  // device->host bytes produced so far
  // Stalls the device->host link (the core's USB writes return 0) until unstalled.
  void set_usb_stalled(bool stalled);
  // A stuck ADC: conversions start but never complete (the core reports ErrorCode::kAdcTimeout).
  void set_adc_stuck(bool stuck);

  // Every GPIO transition so far (all lines, in time order).
  const std::vector<GpioEdge>& gpio_edges() const;
  // Every ADC conversion started: (t_us, channel, raw).
  struct AdcConversion {
    std::uint64_t t_us;
    std::uint8_t channel;
    std::uint16_t raw;
  };
  const std::vector<AdcConversion>& adc_conversions() const;

  const SimulatorOptions& options() const { return options_; }
  Firmware& firmware();

 private:
  SimulatorOptions options_;
  std::unique_ptr<VirtualHal> hal_;
  std::unique_ptr<Firmware> firmware_;
};

}  // namespace hc::fw
