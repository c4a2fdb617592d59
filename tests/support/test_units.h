// Unit factors for writing test inputs in the units their sources use (SI everywhere else).
#pragma once

#include <numbers>

namespace hc::testing {

inline constexpr double kMm = 1e-3;                     // metres per millimetre
inline constexpr double kDeg = std::numbers::pi / 180;  // radians per degree

}  // namespace hc::testing
