// The monotonic clock, for durations (time_s fields, progress) and host timestamps (stamp_ns).
#pragma once

#include <time.h>

#include <chrono>
#include <cstdint>

namespace hc {

// Seconds of std::chrono::steady_clock since t0.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// CLOCK_MONOTONIC in nanoseconds (the host time line devices stamp their samples on).
inline std::int64_t monotonic_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace hc
