// Wall-clock seconds for the summaries' time_s fields.
#pragma once

#include <chrono>

namespace hc::composite::detail {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace hc::composite::detail
