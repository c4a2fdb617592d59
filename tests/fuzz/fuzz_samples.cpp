// libFuzzer target for the force–displacement samples reader: arbitrary bytes are parsed as a
// samples document (TetGen mesh references resolve against a directory that does not exist, so
// only inline meshes can succeed). A successful parse must validate and round-trip.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "processing/material/samples.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::material::Samples> s =
      hc::material::parse_samples(text, "fuzz.json", "/nonexistent-fuzz-dir");
  if (!s.ok()) return 0;
  if (!hc::material::validate_samples(*s).ok()) __builtin_trap();
  if (s->node_file.empty()) {
    const std::string again = hc::dump_json(hc::material::samples_to_json(*s));
    if (!hc::material::parse_samples(again, "again.json", "/nonexistent-fuzz-dir").ok())
      __builtin_trap();
  }
  (void)s->max_displacement_m();
  return 0;
}
