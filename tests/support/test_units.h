// Short names of common/units.h's factors, for test inputs written in the units their sources use.
#pragma once

#include "common/units.h"

namespace hc::testing {

inline constexpr double kMm = units::kMetresPerMillimetre;
inline constexpr double kDeg = units::kRadiansPerDegree;

}  // namespace hc::testing
