// Clocks for devices and the scheduler: the host's monotonic clock, and a simulated clock that
// makes every simulated device (and the tests driving them) deterministic.
//
// All times are signed 64-bit nanoseconds on one time line per clock ("host monotonic ns"):
// CLOCK_MONOTONIC for MonotonicClock, an arbitrary origin (default 0) for SimulatedClock.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>

namespace hc::devices {

using Duration = std::chrono::nanoseconds;

// A source of host monotonic time. Thread-safe: now_ns() and sleep_until_ns() may be called from
// any thread.
class Clock {
 public:
  virtual ~Clock() = default;
  // Current time in ns on this clock's time line; never decreases.
  virtual std::int64_t now_ns() const = 0;
  // Returns once now_ns() >= t_ns (immediately if already past). A simulated clock in
  // auto-advance mode jumps to t_ns instead of waiting.
  virtual void sleep_until_ns(std::int64_t t_ns) = 0;
  // True for SimulatedClock: devices then derive everything from simulated time.
  virtual bool is_simulated() const { return false; }

  void sleep_for(Duration d) { sleep_until_ns(now_ns() + d.count()); }
};

// The host's CLOCK_MONOTONIC (std::chrono::steady_clock on Linux), in ns since boot.
class MonotonicClock final : public Clock {
 public:
  std::int64_t now_ns() const override;
  void sleep_until_ns(std::int64_t t_ns) override;
};

// A process-wide MonotonicClock.
std::shared_ptr<Clock> monotonic_clock();

// Simulated time that moves only when told to. Two modes:
//  * kAutoAdvance (default): sleep_until_ns(t) sets the time to max(now, t) and returns at once, so
//  a
//    single-threaded test (or a replay faster than real time) runs as fast as the CPU allows and
//    produces the same samples on every run.
//  * kManual: sleep_until_ns(t) blocks until another thread calls advance_ns()/set_ns() past t (or
//    until release() is called), for multi-threaded tests that step time explicitly.
class SimulatedClock final : public Clock {
 public:
  enum class Mode { kAutoAdvance, kManual };
  explicit SimulatedClock(std::int64_t start_ns = 0, Mode mode = Mode::kAutoAdvance);

  std::int64_t now_ns() const override;
  void sleep_until_ns(std::int64_t t_ns) override;
  bool is_simulated() const override { return true; }

  // Moves time forward by dt_ns (>= 0; negative values are ignored).
  void advance_ns(std::int64_t dt_ns);
  // Sets the time to t_ns if it is later than now (time never goes back).
  void set_ns(std::int64_t t_ns);
  // kManual only: wakes every sleeper for good (shutdown); later sleeps return at once.
  void release();
  Mode mode() const { return mode_; }

 private:
  const Mode mode_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::int64_t now_ns_;
  bool released_ = false;
};

}  // namespace hc::devices
