// Progress reporting for long-running work. Tools pass a reporter down; libraries report through a
// ProgressTask and never print themselves. On a terminal the console reporter redraws one bar line;
// when stderr is not a terminal, or CI is set, it prints plain lines at most every few seconds.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

namespace hc {

class ProgressReporter {
 public:
  virtual ~ProgressReporter() = default;
  // A task starts; `total` is the number of units of work (0: unknown).
  virtual void begin(std::string_view task, std::uint64_t total) = 0;
  // `done` units of the current task are finished. Thread-safe; cheap enough for inner loops.
  virtual void update(std::uint64_t done) = 0;
  // The current task ended; `summary` is one short line (may be empty).
  virtual void end(std::string_view summary) = 0;
};

enum class ProgressStyle {
  kAuto,  // bar on a terminal, plain lines otherwise (and whenever the CI variable is set)
  kBar,
  kLines,
  kQuiet,
};

// Where and how often the console reporter draws. The defaults are what tools want.
struct ConsoleProgressOptions {
  ProgressStyle style = ProgressStyle::kAuto;
  std::FILE* out = stderr;
  // Shortest time between two bar redraws (~10 Hz: smooth, and cheap on slow terminals).
  std::chrono::milliseconds bar_interval{100};
  // Shortest time between two plain lines, so CI logs stay readable.
  std::chrono::milliseconds line_interval{5000};
  // Tasks that finish sooner than this print nothing at all (no bar, no lines), so that quick steps
  // of a batch do not flood the log; longer ones show their first output after this delay.
  // Zero draws at once.
  std::chrono::milliseconds silent_below{1000};
  // The clock used for throttling, rates and ETAs; empty means std::chrono::steady_clock::now.
  // Tests substitute a manual clock.
  std::function<std::chrono::steady_clock::time_point()> now;
};

// The style kAuto resolves to for `out`: kBar when `out` is a terminal and the CI environment
// variable is unset, kLines otherwise. Other styles are returned unchanged.
ProgressStyle resolve_progress_style(ProgressStyle style, std::FILE* out);

// Reports to stderr.
std::unique_ptr<ProgressReporter> make_console_progress(ProgressStyle style = ProgressStyle::kAuto);
// Reports to options.out. Bar: one line redrawn in place with percent, count, rate and ETA. Lines:
// "task: 40% (400/1000), 1.2 s" at begin, at most every line_interval, and a closing line at end.
// An unknown total (0) shows the count only. A task begun inside another (a library step inside a
// tool's task) suspends the outer one until it ends. update() costs a clock read and two atomics
// unless it is time to draw. Writes never fail loudly: a closed stream is ignored.
std::unique_ptr<ProgressReporter> make_console_progress(const ConsoleProgressOptions& options);

// A reporter that does nothing (what libraries use when the caller passes none).
ProgressReporter& null_progress();

// RAII helper: begin() on construction, end() on destruction. Accepts nullptr (no reporting).
class ProgressTask {
 public:
  ProgressTask(ProgressReporter* reporter, std::string_view task, std::uint64_t total);
  ~ProgressTask();
  ProgressTask(const ProgressTask&) = delete;
  ProgressTask& operator=(const ProgressTask&) = delete;

  void advance(std::uint64_t n = 1);  // thread-safe
  void set(std::uint64_t done);
  void set_summary(std::string summary) { summary_ = std::move(summary); }
  // Seconds since construction.
  double elapsed_s() const;

 private:
  ProgressReporter* reporter_;
  std::atomic<std::uint64_t> done_{0};
  std::string summary_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace hc
