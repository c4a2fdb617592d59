#include "common/log.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>

#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "scoped_env.h"

namespace hc {
namespace {

// Each test starts from the documented default ("info" everywhere, output on stderr) and leaves
// the process that way, since the registry is process-wide.
class LogTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(log::configure("info").ok()); }
  void TearDown() override {
    log::set_sink(nullptr);
    EXPECT_TRUE(log::configure("info").ok());
  }

  // Routes log output into a string for the rest of the test.
  std::ostringstream& capture() {
    log::set_sink(std::make_shared<spdlog::sinks::ostream_sink_mt>(captured_));
    return captured_;
  }

 private:
  std::ostringstream captured_;
};

TEST_F(LogTest, SameLoggerPerModule) {
  EXPECT_EQ(log::get("mesh"), log::get("mesh"));
  EXPECT_NE(log::get("mesh"), log::get("fem"));
  EXPECT_EQ(log::get("mesh")->name(), "mesh");
}

TEST_F(LogTest, SpecWithoutBareLevelDefaultsToInfo) {
  ASSERT_TRUE(log::configure("error").ok());
  ASSERT_TRUE(log::configure("mesh=debug").ok());
  EXPECT_EQ(log::get("log_test_default")->level(), spdlog::level::info);
  EXPECT_EQ(log::get("fem")->level(), spdlog::level::info);
}

TEST_F(LogTest, SingleLevelSetsEveryModule) {
  ASSERT_TRUE(log::configure("warn").ok());
  EXPECT_EQ(log::get("mesh")->level(), spdlog::level::warn);
  EXPECT_EQ(log::get("rig")->level(), spdlog::level::warn);
  EXPECT_EQ(log::get("log_test_new_after_warn")->level(), spdlog::level::warn);
}

TEST_F(LogTest, PerModuleLevelsApplyToExistingAndFutureLoggers) {
  const auto mesh = log::get("mesh");
  ASSERT_TRUE(log::configure("info,mesh=debug,rig=trace,log_test_future=error").ok());
  EXPECT_EQ(mesh->level(), spdlog::level::debug);
  EXPECT_EQ(log::get("rig")->level(), spdlog::level::trace);
  EXPECT_EQ(log::get("fem")->level(), spdlog::level::info);
  EXPECT_EQ(log::get("log_test_future")->level(), spdlog::level::err);
  // A new spec replaces the old one entirely: mesh falls back to the new default.
  ASSERT_TRUE(log::configure("error").ok());
  EXPECT_EQ(mesh->level(), spdlog::level::err);
  EXPECT_EQ(log::get("rig")->level(), spdlog::level::err);
}

TEST_F(LogTest, SpacesCaseAndEmptyEntriesAreTolerated) {
  ASSERT_TRUE(log::configure(" Warning , mesh = DEBUG ,, ").ok());
  EXPECT_EQ(log::get("fem")->level(), spdlog::level::warn);
  EXPECT_EQ(log::get("mesh")->level(), spdlog::level::debug);
  ASSERT_TRUE(log::configure("").ok());
  EXPECT_EQ(log::get("mesh")->level(), spdlog::level::info);
  ASSERT_TRUE(log::configure("mesh=off").ok());
  EXPECT_EQ(log::get("mesh")->level(), spdlog::level::off);
  EXPECT_EQ(log::get("fem")->level(), spdlog::level::info);
}

TEST_F(LogTest, BadEntryIsRejectedAndChangesNothing) {
  ASSERT_TRUE(log::configure("info,mesh=debug").ok());
  const Status s = log::configure("warn,mesh=loud,rig=trace");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(),
            "HARDCOPY_LOG entry 'mesh=loud': unknown level 'loud' (valid levels: trace, debug, "
            "info, warn, error, critical, off)");
  EXPECT_EQ(log::get("mesh")->level(), spdlog::level::debug);
  EXPECT_EQ(log::get("rig")->level(), spdlog::level::info);

  EXPECT_EQ(log::configure("verbose").message(),
            "HARDCOPY_LOG entry 'verbose': unknown level (valid levels: trace, debug, info, warn, "
            "error, critical, off)");
  EXPECT_EQ(log::configure("=debug").message(),
            "HARDCOPY_LOG entry '=debug': missing module name before '='");
  EXPECT_EQ(log::configure("mesh=").code(), StatusCode::kInvalidArgument);
}

TEST_F(LogTest, ConfigureFromEnvironment) {
  {
    testing::ScopedEnv env(log::kEnvVar, "error,rig=debug");
    ASSERT_TRUE(log::configure_from_env().ok());
    EXPECT_EQ(log::get("mesh")->level(), spdlog::level::err);
    EXPECT_EQ(log::get("rig")->level(), spdlog::level::debug);
  }
  {
    // Unset: the current levels stay.
    testing::ScopedEnv env(log::kEnvVar, nullptr);
    ASSERT_TRUE(log::configure_from_env().ok());
    EXPECT_EQ(log::get("mesh")->level(), spdlog::level::err);
  }
  {
    testing::ScopedEnv env(log::kEnvVar, "rig=chatty");
    const Status s = log::configure_from_env();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(s.message().find("'rig=chatty'"), std::string::npos);
  }
}

TEST_F(LogTest, LinesCarryTimeLevelAndModule) {
  std::ostringstream& out = capture();
  log::get("mesh")->warn("repaired {} holes", 3);
  log::get("mesh")->debug("not shown at info");
  const std::regex line(
      R"(\[\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}\] \[warning\] \[mesh\] repaired 3 holes\n)");
  EXPECT_TRUE(std::regex_match(out.str(), line)) << out.str();
}

TEST_F(LogTest, LevelFiltersPerModule) {
  std::ostringstream& out = capture();
  ASSERT_TRUE(log::configure("warn,rig=debug").ok());
  log::get("mesh")->info("mesh info");
  log::get("rig")->debug("rig debug");
  log::get("rig")->trace("rig trace");
  const std::string text = out.str();
  EXPECT_EQ(text.find("mesh info"), std::string::npos);
  EXPECT_NE(text.find("[debug] [rig] rig debug"), std::string::npos) << text;
  EXPECT_EQ(text.find("rig trace"), std::string::npos);
}

TEST_F(LogTest, ConcurrentLoggingKeepsLinesWhole) {
  std::ostringstream& out = capture();
  constexpr int kThreads = 4;
  constexpr int kLinesPerThread = 250;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([t] {
      for (int i = 0; i < kLinesPerThread; ++i)
        log::get("log_test_thread_" + std::to_string((t + i) % 3))->info("t{} line {}", t, i);
    });
  }
  for (auto& thread : threads) thread.join();
  std::istringstream lines(out.str());
  const std::regex whole(R"(\[[^\]]+\] \[info\] \[log_test_thread_\d\] t\d line \d+)");
  int count = 0;
  for (std::string l; std::getline(lines, l); ++count) EXPECT_TRUE(std::regex_match(l, whole)) << l;
  EXPECT_EQ(count, kThreads * kLinesPerThread);
}

}  // namespace
}  // namespace hc
