// libFuzzer target for the Phidget InterfaceKit 8/8/8 report decoder: arbitrary bytes as an HID
// input report. Whatever decodes must re-encode and decode to the same samples, and every
// sensor value must be in 0..1000. Crashes, sanitizer reports and mismatches are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "rig_daemon/backends/phidget_interfacekit.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace ph = hc::rig::phidget;
  auto report = ph::decode_report(std::span<const std::uint8_t>(data, size));
  if (!report.ok()) return 0;
  for (const auto& samples : report->raw) {
    if (samples.size() > ph::kMaxSamplesPerReport) std::abort();
    for (std::uint16_t raw : samples)
      if (raw > 0xFFF || ph::sensor_value(raw) > 1000) std::abort();
  }
  auto bytes = ph::encode_report(*report);
  if (!bytes.ok()) return 0;  // 16 samples in one nibble cannot be re-encoded; fine
  auto again = ph::decode_report(*bytes);
  if (!again.ok() || again->raw != report->raw || again->overruns != report->overruns) std::abort();
  return 0;
}
