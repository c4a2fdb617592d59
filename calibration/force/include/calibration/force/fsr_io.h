// The FSR calibration file (`hardcopy calib fsr S.mcap -o FSR.json`): JSON, one object.
//
//   {
//     "format": "hardcopy.fsr_calibration",     required, exactly this
//     "version": 1,                             required, 1
//     "device": "fsr",                          optional string
//     "model": "power_law",                     required: "power_law" | "piecewise_linear" (the
//                                               model to_newtons uses)
//     "power_law": {                            required when model = power_law, else optional
//       "full_scale": 4095,                     raw at full scale, > 0
//       "threshold": 0.02,                      fraction of full scale, 0 <= t < 1
//       "scale_n": 60.0,                        N at full scale, > 0
//       "exponent": 1.6,                        > 0
//       "threshold_std": 0.0001, "scale_n_std": 0.1, "exponent_std": 0.001   optional, >= 0
//     },
//     "piecewise_linear": {                     required when model = piecewise_linear
//       "raw": [100, 400, ...],                 >= 2 knots, strictly increasing, finite
//       "force_n": [0.6, 3.1, ...]              same count, non-decreasing, finite
//     },
//     "fit": {"pairs": 812, "power_law": {"rms_n": .., "r2": .., ...}, "piecewise_linear": {..}}
//                                               optional, informational (not read back)
//   }
// F = 0 below the power law's threshold; piecewise-linear forces extrapolate along the end
// segments and are clamped at 0. Unknown keys are ignored (forward compatible).
#pragma once

#include <filesystem>
#include <string_view>

#include "calibration/force/fsr_fit.h"
#include "common/json.h"
#include "common/status.h"

namespace hc::calib {

inline constexpr std::string_view kFsrCalibrationFormat = "hardcopy.fsr_calibration";
inline constexpr int kFsrCalibrationVersion = 1;

Json fsr_curve_to_json(const FsrCurve& curve);
// Validates as described above; kInvalidArgument "NAME: key: what" on anything wrong.
Result<FsrCurve> fsr_curve_from_json(const Json& json, std::string_view name);
// Parses text (fuzzing, tests) then fsr_curve_from_json.
Result<FsrCurve> parse_fsr_calibration(std::string_view text, std::string_view name);

// Atomic write (nothing half-written on error).
Status write_fsr_calibration(const std::filesystem::path& path, const FsrCurve& curve);
Result<FsrCurve> read_fsr_calibration(const std::filesystem::path& path);

}  // namespace hc::calib
