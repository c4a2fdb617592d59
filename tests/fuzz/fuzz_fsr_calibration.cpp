// libFuzzer target for the FSR calibration reader (calibration/force/fsr_io.h): arbitrary bytes are
// parsed as an FSR calibration file. A successful parse must evaluate to finite, non-negative
// forces and survive a write/read round trip with the same forces.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "calibration/force/fsr_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hc::Result<hc::calib::FsrCurve> c = hc::calib::parse_fsr_calibration(text, "fuzz.json");
  if (!c.ok()) return 0;
  const std::string again = hc::dump_json(hc::calib::fsr_curve_to_json(*c));
  hc::Result<hc::calib::FsrCurve> back = hc::calib::parse_fsr_calibration(again, "again.json");
  if (!back.ok()) __builtin_trap();
  for (double raw : {-1.0, 0.0, 1.0, 100.0, 1000.0, 4095.0, 1e6}) {
    const double f = c->to_newtons(raw);
    if (std::isnan(f) || f < 0.0) __builtin_trap();
    const double g = back->to_newtons(raw);
    if (!(f == g || (std::isinf(f) && std::isinf(g)))) __builtin_trap();
  }
  return 0;
}
