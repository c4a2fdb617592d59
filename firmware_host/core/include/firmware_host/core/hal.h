// Hardware-abstraction interface of the firmware core: the only way the core touches peripherals.
// A microcontroller port implements it over its timer (output compare), GPIO, ADC and USB device
// stack and calls Firmware's interrupt entry points from the matching ISRs; the simulator
// implements it over virtual peripherals. Freestanding (no heap, no OS).
#pragma once

#include <cstddef>
#include <cstdint>

namespace hc::fw {

class Hal {
 public:
  // Free-running µs counter since boot (64-bit so it never wraps in practice).
  virtual std::uint64_t now_us() = 0;
  // Arms the one-shot compare interrupt: at (or, if `at_us` is already past, immediately after)
  // `at_us` the platform calls Firmware::on_timer() once. Re-arming replaces the previous compare.
  virtual void timer_arm(std::uint64_t at_us) = 0;
  virtual void timer_disarm() = 0;
  // Drives the trigger output lines in `lines_mask` high / low (bit i = line i), atomically.
  virtual void gpio_set(std::uint8_t lines_mask) = 0;
  virtual void gpio_clear(std::uint8_t lines_mask) = 0;
  // Starts one conversion on `channel` (sample-and-hold at the call); on completion the platform
  // calls Firmware::on_adc_complete(), which reads the result with adc_read().
  virtual void adc_start(std::uint8_t channel) = 0;
  virtual std::uint16_t adc_read() = 0;
  // USB bulk IN (device -> host): queues up to `size` bytes, returns how many were accepted (0 when
  // the endpoint buffer is full). Non-blocking.
  virtual std::size_t usb_write(const std::uint8_t* data, std::size_t size) = 0;
  // USB bulk OUT (host -> device): copies up to `cap` received bytes, returns the count.
  // Non-blocking.
  virtual std::size_t usb_read(std::uint8_t* out, std::size_t cap) = 0;
  // Masks / unmasks the timer and ADC interrupts around main-loop updates of sequencer state.
  virtual void enter_critical() = 0;
  virtual void exit_critical() = 0;

 protected:
  ~Hal() = default;  // never deleted through Hal (no heap in the core)
};

}  // namespace hc::fw
