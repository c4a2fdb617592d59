// libFuzzer target for the ATI Net F/T RDT decoders: arbitrary bytes as a response datagram, as a
// request, and as the calibration XML; decoded records are re-encoded (must give the same bytes),
// converted to SI and fed to the sequence tracker. Errors are the expected outcome; crashes,
// sanitizer reports and round-trip mismatches are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string_view>

#include "rig_daemon/backends/rdt.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace rdt = hc::rig::rdt;
  const std::span<const std::uint8_t> bytes(data, size);
  auto records = rdt::decode_records(bytes);
  if (records.ok()) {
    if (rdt::encode_records(*records) != std::vector<std::uint8_t>(data, data + size)) std::abort();
    rdt::SequenceTracker tracker;
    const rdt::Calibration cal{1e6, 1e3, "N", "Nmm"};
    for (const rdt::Record& r : *records) {
      tracker.update(r.rdt_sequence);
      const rdt::Wrench w = rdt::to_si(r.counts, cal);
      if (rdt::to_counts(w, cal) != r.counts) std::abort();
    }
  }
  auto request = rdt::decode_request(bytes);
  if (request.ok()) {
    const auto again = rdt::encode_request(*request);
    if (!std::equal(again.begin(), again.end(), data)) std::abort();
  }
  auto cal =
      rdt::parse_calibration_xml(std::string_view(reinterpret_cast<const char*>(data), size));
  if (cal.ok() && !rdt::validate(*cal).ok()) std::abort();
  return 0;
}
