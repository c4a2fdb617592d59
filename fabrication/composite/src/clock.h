// Wall-clock seconds for the summaries' time_s fields.
#pragma once

#include <chrono>

#include "common/clock.h"

namespace hc::composite::detail {

using Clock = std::chrono::steady_clock;
using hc::seconds_since;

}  // namespace hc::composite::detail
