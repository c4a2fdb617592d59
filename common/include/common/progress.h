// Progress reporting for long-running work. Tools pass a reporter down; libraries report through a
// ProgressTask and never print themselves. On a terminal the console reporter redraws one bar line;
// when stderr is not a terminal, or CI is set, it prints plain lines at most every few seconds.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
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
  kAuto,   // bar on a terminal, plain lines otherwise (and whenever the CI variable is set)
  kBar,
  kLines,
  kQuiet,
};

// Reports to stderr.
std::unique_ptr<ProgressReporter> make_console_progress(ProgressStyle style = ProgressStyle::kAuto);

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
