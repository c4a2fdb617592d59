// A scripted HAL for the firmware core's unit tests: a manual µs clock, a log of GPIO writes, ADC
// values from a table or function, byte queues for USB, and a tiny scheduler that fires the timer
// and ADC interrupts in time order while calling the main loop at a fixed period.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <vector>

#include "firmware_host/core/firmware.h"
#include "firmware_host/protocol/messages.h"

namespace hc::fw::testing {

struct GpioWrite {
  std::uint64_t t_us;
  std::uint8_t mask;
  bool high;
};

class FakeHal final : public Hal {
 public:
  std::uint64_t now = 1'000;  // boot + 1 ms
  std::optional<std::uint64_t> armed;
  std::vector<GpioWrite> gpio;
  std::uint8_t lines = 0;
  std::optional<std::uint64_t> adc_done_at;
  std::uint8_t adc_channel = 0;
  std::uint16_t adc_value = 0;
  std::uint32_t adc_conversion_us = 3;
  bool adc_never_completes = false;
  std::uint32_t isr_latency_us = 0;
  std::function<std::uint16_t(std::uint8_t channel, std::uint64_t t_us)> adc_source =
      [](std::uint8_t channel, std::uint64_t t_us) {
        return static_cast<std::uint16_t>((channel * 1000 + t_us / 100) & 0x0FFF);
      };
  std::deque<std::uint8_t> to_device;
  std::vector<std::uint8_t> from_device;
  bool usb_stalled = false;
  std::size_t usb_packet = 64;  // bytes accepted per usb_write call
  int critical_depth = 0;
  int max_critical_depth = 0;

  std::uint64_t now_us() override { return now; }
  void timer_arm(std::uint64_t at_us) override { armed = at_us; }
  void timer_disarm() override { armed.reset(); }
  void gpio_set(std::uint8_t mask) override {
    lines = static_cast<std::uint8_t>(lines | mask);
    gpio.push_back({now, mask, true});
  }
  void gpio_clear(std::uint8_t mask) override {
    lines = static_cast<std::uint8_t>(lines & ~mask);
    gpio.push_back({now, mask, false});
  }
  void adc_start(std::uint8_t channel) override {
    adc_channel = channel;
    adc_value = adc_source(channel, now);
    if (!adc_never_completes) adc_done_at = now + adc_conversion_us;
  }
  std::uint16_t adc_read() override { return adc_value; }
  std::size_t usb_write(const std::uint8_t* data, std::size_t size) override {
    if (usb_stalled) return 0;
    const std::size_t n = std::min(size, usb_packet);
    from_device.insert(from_device.end(), data, data + n);
    return n;
  }
  std::size_t usb_read(std::uint8_t* out, std::size_t cap) override {
    std::size_t n = 0;
    while (n < cap && !to_device.empty()) {
      out[n++] = to_device.front();
      to_device.pop_front();
    }
    return n;
  }
  void enter_critical() override {
    ++critical_depth;
    max_critical_depth = std::max(max_critical_depth, critical_depth);
  }
  void exit_critical() override { --critical_depth; }

  void send(const Message& m) {
    std::uint8_t buf[kMaxFrameSize];
    const std::size_t n = encode_frame(m, buf, sizeof buf);
    to_device.insert(to_device.end(), buf, buf + n);
  }
};

// Runs the core until `until_us`: timer and ADC interrupts fire at their times (timer first on a
// tie), the main loop every `loop_us`.
inline void run_until(FakeHal& hal, Firmware& fw, std::uint64_t until_us,
                      std::uint64_t loop_us = 100) {
  std::uint64_t next_loop = hal.now;
  for (;;) {
    std::uint64_t t_timer =
        hal.armed ? std::max(*hal.armed, hal.now) + hal.isr_latency_us : UINT64_MAX;
    const std::uint64_t t_adc = hal.adc_done_at ? *hal.adc_done_at : UINT64_MAX;
    const std::uint64_t t = std::min({t_timer, t_adc, next_loop});
    if (t > until_us) break;
    hal.now = t;
    if (t == t_timer) {
      hal.armed.reset();
      fw.on_timer();
    } else if (t == t_adc) {
      hal.adc_done_at.reset();
      fw.on_adc_complete();
    } else {
      fw.poll();
      next_loop += loop_us;
    }
  }
  hal.now = until_us;
}

// Decodes everything the device sent so far (and clears it).
inline std::vector<Message> received(FakeHal& hal, StreamDecoder& decoder) {
  std::vector<Message> out;
  const std::uint8_t* p = hal.from_device.data();
  const std::uint8_t* end = p + hal.from_device.size();
  Message m;
  DecodeError e;
  for (;;) {
    const auto r = decoder.next(&p, end, &m, &e);
    if (r == StreamDecoder::Result::kNeedMore) break;
    if (r == StreamDecoder::Result::kMessage) out.push_back(m);
  }
  hal.from_device.clear();
  return out;
}

}  // namespace hc::fw::testing
