#include "common/progress.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "scoped_env.h"

namespace hc {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Records every call, so tests can check what a ProgressTask reports.
class RecordingReporter : public ProgressReporter {
 public:
  void begin(std::string_view task, std::uint64_t total) override {
    std::lock_guard lock(mutex_);
    events_.push_back("begin " + std::string(task) + " " + std::to_string(total));
  }
  void update(std::uint64_t done) override {
    std::lock_guard lock(mutex_);
    updates_.push_back(done);
  }
  void end(std::string_view summary) override {
    std::lock_guard lock(mutex_);
    events_.push_back("end " + std::string(summary));
  }
  std::vector<std::string> events() const {
    std::lock_guard lock(mutex_);
    return events_;
  }
  std::vector<std::uint64_t> updates() const {
    std::lock_guard lock(mutex_);
    return updates_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> events_;
  std::vector<std::uint64_t> updates_;
};

// A temporary file standing in for stderr: not a terminal, and readable afterwards.
class CapturedStream {
 public:
  CapturedStream() : file_(std::tmpfile()) {}
  ~CapturedStream() {
    if (file_) std::fclose(file_);
  }
  CapturedStream(const CapturedStream&) = delete;
  CapturedStream& operator=(const CapturedStream&) = delete;
  std::FILE* get() const { return file_; }
  std::string text() const {
    std::fflush(file_);
    const long end = std::ftell(file_);
    std::string out(static_cast<std::size_t>(end), '\0');
    std::rewind(file_);
    const std::size_t got = std::fread(out.data(), 1, out.size(), file_);
    out.resize(got);
    std::fseek(file_, 0, SEEK_END);
    return out;
  }

 private:
  std::FILE* file_;
};

// A clock the test moves by hand.
struct ManualClock {
  Clock::time_point now{};
  void advance(Clock::duration d) { now += d; }
};

std::unique_ptr<ProgressReporter> make_reporter(ProgressStyle style, const CapturedStream& out,
                                                ManualClock& clock) {
  ConsoleProgressOptions options;
  options.style = style;
  options.out = out.get();
  options.now = [&clock] { return clock.now; };
  options.silent_below = std::chrono::milliseconds(0);  // these tests read every line
  return make_console_progress(options);
}

TEST(ProgressTask, ReportsBeginUpdatesAndEnd) {
  RecordingReporter reporter;
  {
    ProgressTask task(&reporter, "repair", 10);
    task.advance();
    task.advance(3);
    task.set(7);
    task.set_summary("3 holes filled");
    EXPECT_GE(task.elapsed_s(), 0.0);
  }
  EXPECT_EQ(reporter.events(), (std::vector<std::string>{"begin repair 10", "end 3 holes filled"}));
  EXPECT_EQ(reporter.updates(), (std::vector<std::uint64_t>{1, 4, 7}));
}

TEST(ProgressTask, AcceptsNoReporter) {
  ProgressTask task(nullptr, "silent", 5);
  task.advance(2);
  task.set(5);
  EXPECT_GE(task.elapsed_s(), 0.0);
}

TEST(ProgressTask, AdvanceFromManyThreadsCountsEveryUnit) {
  RecordingReporter reporter;
  constexpr int kThreads = 4;
  constexpr int kPerThread = 1000;
  {
    ProgressTask task(&reporter, "parallel", kThreads * kPerThread);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
      threads.emplace_back([&task] {
        for (int i = 0; i < kPerThread; ++i) task.advance();
      });
    for (auto& thread : threads) thread.join();
  }
  std::vector<std::uint64_t> updates = reporter.updates();
  ASSERT_EQ(updates.size(), static_cast<std::size_t>(kThreads * kPerThread));
  // fetch_add hands out each running total exactly once.
  std::sort(updates.begin(), updates.end());
  for (std::size_t i = 0; i < updates.size(); ++i) ASSERT_EQ(updates[i], i + 1);
}

TEST(NullProgress, IsOneSharedInstance) {
  EXPECT_EQ(&null_progress(), &null_progress());
  ProgressTask task(&null_progress(), "ignored", 3);
  task.advance();
}

TEST(ConsoleProgress, LinesAtBeginEveryFiveSecondsAndEnd) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kLines, out, clock);
  progress->begin("mesh repair", 1000);
  clock.advance(1s);
  progress->update(100);  // too soon after the first line
  clock.advance(4s);
  progress->update(400);  // 5 s: due
  clock.advance(1s);
  progress->update(500);
  clock.advance(1500ms);
  progress->update(600);  // 7.5 s: only 2.5 s since the last line
  clock.advance(2500ms);
  progress->update(900);  // 10 s
  clock.advance(500ms);
  progress->end("12 holes filled");
  EXPECT_EQ(out.text(),
            "mesh repair: 0% (0/1000), 0.0 s\n"
            "mesh repair: 40% (400/1000), 5.0 s\n"
            "mesh repair: 90% (900/1000), 10.0 s\n"
            "mesh repair: done (900/1000) in 10.5 s: 12 holes filled\n");
}

TEST(ConsoleProgress, LinesWithUnknownTotalShowTheCountOnly) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kLines, out, clock);
  progress->begin("scan", 0);
  clock.advance(5s);
  progress->update(1234);
  clock.advance(1s);
  progress->end("");
  EXPECT_EQ(out.text(), "scan: 0, 0.0 s\nscan: 1234, 5.0 s\nscan: done (1234) in 6.0 s\n");
}

TEST(ConsoleProgress, CountNeverGoesBackwards) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kLines, out, clock);
  progress->begin("t", 10);
  progress->update(6);
  clock.advance(5s);
  progress->update(4);  // a slower thread reporting late
  progress->end("");
  EXPECT_EQ(out.text(), "t: 0% (0/10), 0.0 s\nt: 60% (6/10), 5.0 s\nt: done (6/10) in 5.0 s\n");
}

TEST(ConsoleProgress, PercentIsClampedAndSafeForHugeTotals) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kLines, out, clock);
  const std::uint64_t huge = std::numeric_limits<std::uint64_t>::max();
  progress->begin("big", huge);
  clock.advance(5s);
  progress->update(huge / 2);
  progress->end("");
  progress->begin("over", 10);
  clock.advance(5s);
  progress->update(15);
  progress->end("");
  const std::string text = out.text();
  EXPECT_NE(text.find("big: 50% (9223372036854775807/18446744073709551615), 5.0 s\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("over: 100% (15/10), 5.0 s\n"), std::string::npos) << text;
}

TEST(ConsoleProgress, NestedTaskSuspendsAndResumesTheOuterOne) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kLines, out, clock);
  progress->begin("outer", 10);
  progress->update(3);
  progress->begin("inner", 5);
  progress->update(5);
  clock.advance(1s);
  progress->end("");
  progress->end("ok");
  EXPECT_EQ(out.text(),
            "outer: 0% (0/10), 0.0 s\n"
            "inner: 0% (0/5), 0.0 s\n"
            "inner: done (5/5) in 1.0 s\n"
            "outer: done (3/10) in 1.0 s: ok\n");
}

TEST(ConsoleProgress, BarShowsPercentCountRateAndEta) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kBar, out, clock);
  progress->begin("fit", 200);
  clock.advance(50ms);
  progress->update(10);  // within 100 ms of the last draw: skipped
  clock.advance(1950ms);
  progress->update(100);  // 2 s: 50 units/s, 100 left -> ETA 2 s
  clock.advance(2s);
  progress->end("rms 0.3 mm");
  EXPECT_EQ(out.text(),
            "\rfit [........................]   0% 0/200 -/s ETA -\x1b[K"
            "\rfit [############............]  50% 100/200 50/s ETA 2s\x1b[K"
            "\rfit: done (100/200) in 4.0 s: rms 0.3 mm\x1b[K\n");
}

TEST(ConsoleProgress, BarWithUnknownTotalAndLongEta) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kBar, out, clock);
  progress->begin("frames", 0);
  clock.advance(2s);
  progress->update(30000);
  progress->end("");
  progress->begin("slow", 10000);
  clock.advance(10s);
  progress->update(50);  // 5 units/s, 9950 left -> 1990 s
  progress->end("");
  const std::string text = out.text();
  EXPECT_NE(text.find("\rframes 30000 15.0k/s 2.0 s\x1b[K"), std::string::npos) << text;
  EXPECT_NE(text.find("\rslow [........................]   0% 50/10000 5/s ETA 33m10s\x1b[K"),
            std::string::npos)
      << text;
}

TEST(ConsoleProgress, BarRedrawsAtMostTenTimesASecond) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kBar, out, clock);
  progress->begin("busy", 1000);
  for (int i = 1; i <= 1000; ++i) {
    clock.advance(1ms);
    progress->update(static_cast<std::uint64_t>(i));
  }
  const std::string text = out.text();
  // The first draw at begin, then one per 100 ms over one second.
  EXPECT_EQ(std::count(text.begin(), text.end(), '\r'), 11);
  progress->end("");
}

TEST(ConsoleProgress, QuietWritesNothing) {
  CapturedStream out;
  ManualClock clock;
  auto progress = make_reporter(ProgressStyle::kQuiet, out, clock);
  progress->begin("q", 10);
  clock.advance(10s);
  progress->update(5);
  progress->end("done");
  EXPECT_EQ(out.text(), "");
}

TEST(ConsoleProgress, ConcurrentUpdatesDrawWholeBars) {
  CapturedStream out;
  ConsoleProgressOptions options;
  options.style = ProgressStyle::kBar;
  options.out = out.get();
  options.bar_interval = std::chrono::milliseconds(0);  // draw as often as threads allow
  options.silent_below = std::chrono::milliseconds(0);
  auto progress = make_console_progress(options);
  progress->begin("race", 40000);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&progress, t] {
      for (std::uint64_t i = 0; i < 10000; ++i)
        progress->update(static_cast<std::uint64_t>(t) * 10000 + i);
    });
  for (auto& thread : threads) thread.join();
  progress->end("");
  const std::string text = out.text();
  const std::regex bar(R"(race \[[#.]{24}\] +\d+% \d+/40000 \S+/s ETA \S+\x1b\[K)");
  std::size_t pos = 0, bars = 0;
  while ((pos = text.find('\r', pos)) != std::string::npos) {
    const std::size_t next = text.find('\r', pos + 1);
    const std::string piece =
        text.substr(pos + 1, next == std::string::npos ? next : next - pos - 1);
    if (piece.rfind("race: done", 0) != 0) {
      EXPECT_TRUE(std::regex_match(piece, bar)) << piece;
      ++bars;
    }
    pos += 1;
  }
  EXPECT_GE(bars, 1u);
  EXPECT_NE(text.find("race: done (39999/40000)"), std::string::npos);
}

TEST(ProgressStyle, AutoIsLinesWhenNotATerminal) {
  CapturedStream out;
  testing::ScopedEnv ci("CI", nullptr);
  EXPECT_EQ(resolve_progress_style(ProgressStyle::kAuto, out.get()), ProgressStyle::kLines);
  EXPECT_EQ(resolve_progress_style(ProgressStyle::kBar, out.get()), ProgressStyle::kBar);
  EXPECT_EQ(resolve_progress_style(ProgressStyle::kQuiet, out.get()), ProgressStyle::kQuiet);
  EXPECT_EQ(resolve_progress_style(ProgressStyle::kLines, out.get()), ProgressStyle::kLines);
}

TEST(ProgressStyle, AutoOnATerminalIsBarUnlessCiIsSet) {
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0)
    GTEST_SKIP() << "no pseudo-terminal available";
  const char* name = ::ptsname(master);
  ASSERT_NE(name, nullptr);
  std::FILE* terminal = std::fopen(name, "w");
  ASSERT_NE(terminal, nullptr);
  {
    testing::ScopedEnv ci("CI", nullptr);
    EXPECT_EQ(resolve_progress_style(ProgressStyle::kAuto, terminal), ProgressStyle::kBar);
  }
  {
    testing::ScopedEnv ci("CI", "true");
    EXPECT_EQ(resolve_progress_style(ProgressStyle::kAuto, terminal), ProgressStyle::kLines);
  }
  std::fclose(terminal);
  ::close(master);
}

}  // namespace
}  // namespace hc

namespace hc {
namespace {

TEST(ConsoleProgress, ShortTasksPrintNothingLongOnesAfterTheDelay) {
  CapturedStream out;
  ManualClock clock;
  ConsoleProgressOptions options;
  options.style = ProgressStyle::kLines;
  options.out = out.get();
  options.now = [&clock] { return clock.now; };
  options.silent_below = std::chrono::milliseconds(1000);
  auto progress = make_console_progress(options);

  progress->begin("quick", 10);
  clock.advance(std::chrono::milliseconds(300));
  progress->update(10);
  progress->end("fine");
  EXPECT_EQ(out.text(), "") << "a task under silent_below prints nothing";

  progress->begin("slow", 10);
  clock.advance(std::chrono::milliseconds(999));
  progress->update(3);
  EXPECT_EQ(out.text(), "");
  clock.advance(std::chrono::milliseconds(1));
  progress->update(4);
  clock.advance(std::chrono::milliseconds(1000));
  progress->end("");
  EXPECT_EQ(out.text(), "slow: 40% (4/10), 1.0 s\nslow: done (4/10) in 2.0 s\n");
}

}  // namespace
}  // namespace hc
