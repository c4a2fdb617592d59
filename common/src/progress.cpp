#include "common/progress.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <mutex>
#include <utility>
#include <vector>

namespace hc {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kBarWidth = 24;                  // characters between the brackets
constexpr const char* kClearToEol = "\x1b[K";  // ANSI "erase to end of line"

// 1234 -> "1234", 12345 -> "12.3k", 1.5e6 -> "1.5M": rates stay short on the bar line.
std::string short_number(double v) {
  if (v < 1e4) return fmt::format("{:.0f}", v);
  if (v < 1e6) return fmt::format("{:.1f}k", v / 1e3);
  if (v < 1e9) return fmt::format("{:.1f}M", v / 1e6);
  return fmt::format("{:.1f}G", v / 1e9);
}

// 42 -> "42s", 185 -> "3m05s", 7260 -> "2h01m".
std::string short_duration(double s) {
  const auto total = static_cast<std::uint64_t>(std::llround(std::max(0.0, s)));
  if (total < 60) return fmt::format("{}s", total);
  if (total < 3600) return fmt::format("{}m{:02}s", total / 60, total % 60);
  return fmt::format("{}h{:02}m", total / 3600, (total % 3600) / 60);
}

int percent(std::uint64_t done, std::uint64_t total) {
  if (total == 0) return 0;
  // In double so that huge totals cannot overflow done * 100.
  const double p = 100.0 * static_cast<double>(done) / static_cast<double>(total);
  return static_cast<int>(std::min(100.0, std::floor(p)));
}

class NullProgress final : public ProgressReporter {
 public:
  void begin(std::string_view, std::uint64_t) override {}
  void update(std::uint64_t) override {}
  void end(std::string_view) override {}
};

class ConsoleProgress final : public ProgressReporter {
 public:
  explicit ConsoleProgress(const ConsoleProgressOptions& options)
      : style_(options.out ? resolve_progress_style(options.style, options.out)
                           : ProgressStyle::kQuiet),
        out_(options.out),
        interval_ns_(std::chrono::nanoseconds(style_ == ProgressStyle::kBar ? options.bar_interval
                                                                            : options.line_interval)
                         .count()),
        silent_below_ns_(std::chrono::nanoseconds(options.silent_below).count()),
        now_(options.now ? options.now : [] { return Clock::now(); }) {}

  ~ConsoleProgress() override {
    // Leave the cursor on a fresh line if a bar was still showing.
    std::lock_guard lock(mutex_);
    if (style_ == ProgressStyle::kBar && bar_showing_) write("\n");
  }

  void begin(std::string_view task, std::uint64_t total) override {
    std::lock_guard lock(mutex_);
    // A task started inside another one (a library step inside a tool's task) suspends the outer
    // task; end() resumes it.
    if (!tasks_.empty()) tasks_.back().done = done_.load(std::memory_order_relaxed);
    const Clock::time_point now = now_();
    tasks_.push_back({std::string(task), total, now, 0, false});
    done_.store(0, std::memory_order_relaxed);
    if (silent_below_ns_ > 0) {
      next_draw_ns_.store(ticks(now) + silent_below_ns_, std::memory_order_relaxed);
    } else {
      next_draw_ns_.store(ticks(now) + interval_ns_, std::memory_order_relaxed);
      draw(now);
    }
  }

  void update(std::uint64_t done) override {
    // Keep the largest value: threads finishing out of order must not move the count backwards.
    std::uint64_t seen = done_.load(std::memory_order_relaxed);
    while (seen < done && !done_.compare_exchange_weak(seen, done, std::memory_order_relaxed)) {
    }
    if (style_ == ProgressStyle::kQuiet) return;
    const Clock::time_point now = now_();
    std::int64_t next = next_draw_ns_.load(std::memory_order_relaxed);
    if (ticks(now) < next) return;
    // One thread wins the right to draw; the others go back to work at once.
    if (!next_draw_ns_.compare_exchange_strong(next, ticks(now) + interval_ns_,
                                               std::memory_order_relaxed))
      return;
    std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    draw(now);
  }

  void end(std::string_view summary) override {
    std::lock_guard lock(mutex_);
    if (tasks_.empty()) return;
    const Clock::time_point now = now_();
    const Task& task = tasks_.back();
    const std::uint64_t done = done_.load(std::memory_order_relaxed);
    const bool worth_a_line = task.drawn || ticks(now) - ticks(task.start) >= silent_below_ns_;
    if (style_ != ProgressStyle::kQuiet && worth_a_line) {
      std::string line = task.total == 0 ? fmt::format("{}: done ({}) in {:.1f} s", task.name, done,
                                                       seconds(now - task.start))
                                         : fmt::format("{}: done ({}/{}) in {:.1f} s", task.name,
                                                       done, task.total, seconds(now - task.start));
      if (!summary.empty()) line += fmt::format(": {}", summary);
      if (style_ == ProgressStyle::kBar) {
        write(fmt::format("\r{}{}\n", line, kClearToEol));
        bar_showing_ = false;
      } else {
        write(line + "\n");
      }
    }
    tasks_.pop_back();
    if (!tasks_.empty()) {
      done_.store(tasks_.back().done, std::memory_order_relaxed);
      next_draw_ns_.store(ticks(now) + interval_ns_, std::memory_order_relaxed);
      if (style_ == ProgressStyle::kBar) draw(now);
    }
  }

 private:
  struct Task {
    std::string name;
    std::uint64_t total;
    Clock::time_point start;
    std::uint64_t done;  // saved while a nested task runs
    bool drawn;          // something was printed for this task
  };

  static std::int64_t ticks(Clock::time_point t) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
  }
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

  // Caller holds mutex_.
  void draw(Clock::time_point now) {
    if (tasks_.empty() || style_ == ProgressStyle::kQuiet) return;
    Task& task = tasks_.back();
    task.drawn = true;
    const std::uint64_t done = done_.load(std::memory_order_relaxed);
    const double elapsed = seconds(now - task.start);
    if (style_ == ProgressStyle::kLines) {
      if (task.total == 0) {
        write(fmt::format("{}: {}, {:.1f} s\n", task.name, done, elapsed));
      } else {
        write(fmt::format("{}: {}% ({}/{}), {:.1f} s\n", task.name, percent(done, task.total), done,
                          task.total, elapsed));
      }
      return;
    }
    const double rate = elapsed > 0 ? static_cast<double>(done) / elapsed : 0.0;
    const std::string rate_text = elapsed > 0 ? short_number(rate) + "/s" : "-/s";
    std::string line;
    if (task.total == 0) {
      line = fmt::format("{} {} {} {:.1f} s", task.name, done, rate_text, elapsed);
    } else {
      const int p = percent(done, task.total);
      const int filled = p * kBarWidth / 100;
      const std::uint64_t left = done < task.total ? task.total - done : 0;
      const std::string eta =
          rate > 0 ? short_duration(static_cast<double>(left) / rate) : std::string("-");
      line = fmt::format("{} [{}{}] {:3}% {}/{} {} ETA {}", task.name, std::string(filled, '#'),
                         std::string(kBarWidth - filled, '.'), p, done, task.total, rate_text, eta);
    }
    write(fmt::format("\r{}{}", line, kClearToEol));
    bar_showing_ = true;
  }

  void write(const std::string& text) {
    // A closed or full stream must not stop the work being reported on: errors are ignored.
    std::fwrite(text.data(), 1, text.size(), out_);
    std::fflush(out_);
  }

  const ProgressStyle style_;
  std::FILE* const out_;
  const std::int64_t interval_ns_;
  const std::int64_t silent_below_ns_;
  const std::function<Clock::time_point()> now_;

  std::atomic<std::uint64_t> done_{0};
  std::atomic<std::int64_t> next_draw_ns_{0};
  std::mutex mutex_;  // guards tasks_, bar_showing_ and the stream
  std::vector<Task> tasks_;
  bool bar_showing_ = false;
};

}  // namespace

ProgressStyle resolve_progress_style(ProgressStyle style, std::FILE* out) {
  if (style != ProgressStyle::kAuto) return style;
  if (out == nullptr) return ProgressStyle::kQuiet;
  const bool terminal = ::isatty(::fileno(out)) == 1;
  const bool ci = std::getenv("CI") != nullptr;
  return terminal && !ci ? ProgressStyle::kBar : ProgressStyle::kLines;
}

std::unique_ptr<ProgressReporter> make_console_progress(ProgressStyle style) {
  ConsoleProgressOptions options;
  options.style = style;
  return make_console_progress(options);
}

std::unique_ptr<ProgressReporter> make_console_progress(const ConsoleProgressOptions& options) {
  return std::make_unique<ConsoleProgress>(options);
}

ProgressReporter& null_progress() {
  static NullProgress instance;
  return instance;
}

ProgressTask::ProgressTask(ProgressReporter* reporter, std::string_view task, std::uint64_t total)
    : reporter_(reporter), start_(std::chrono::steady_clock::now()) {
  if (reporter_) reporter_->begin(task, total);
}

ProgressTask::~ProgressTask() {
  if (reporter_) reporter_->end(summary_);
}

void ProgressTask::advance(std::uint64_t n) {
  const std::uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
  if (reporter_) reporter_->update(done);
}

void ProgressTask::set(std::uint64_t done) {
  done_.store(done, std::memory_order_relaxed);
  if (reporter_) reporter_->update(done);
}

double ProgressTask::elapsed_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

}  // namespace hc
