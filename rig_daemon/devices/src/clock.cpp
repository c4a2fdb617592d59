#include "rig_daemon/devices/clock.h"

#include <algorithm>
#include <thread>

namespace hc::devices {

std::int64_t MonotonicClock::now_ns() const {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void MonotonicClock::sleep_until_ns(std::int64_t t_ns) {
  std::this_thread::sleep_until(
      std::chrono::steady_clock::time_point(std::chrono::nanoseconds(t_ns)));
}

std::shared_ptr<Clock> monotonic_clock() {
  static const std::shared_ptr<Clock> clock = std::make_shared<MonotonicClock>();
  return clock;
}

SimulatedClock::SimulatedClock(std::int64_t start_ns, Mode mode) : mode_(mode), now_ns_(start_ns) {}

std::int64_t SimulatedClock::now_ns() const {
  std::lock_guard lock(mutex_);
  return now_ns_;
}

void SimulatedClock::sleep_until_ns(std::int64_t t_ns) {
  std::unique_lock lock(mutex_);
  if (mode_ == Mode::kAutoAdvance) {
    now_ns_ = std::max(now_ns_, t_ns);
    return;
  }
  cv_.wait(lock, [&] { return released_ || now_ns_ >= t_ns; });
}

void SimulatedClock::advance_ns(std::int64_t dt_ns) {
  if (dt_ns <= 0) return;
  {
    std::lock_guard lock(mutex_);
    now_ns_ += dt_ns;
  }
  cv_.notify_all();
}

void SimulatedClock::set_ns(std::int64_t t_ns) {
  {
    std::lock_guard lock(mutex_);
    now_ns_ = std::max(now_ns_, t_ns);
  }
  cv_.notify_all();
}

void SimulatedClock::release() {
  {
    std::lock_guard lock(mutex_);
    released_ = true;
  }
  cv_.notify_all();
}

}  // namespace hc::devices
