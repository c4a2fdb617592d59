// The live page in a real browser: Debian's headless chromium, driven by playwright-core
// (tests/browser/live_page.mjs), loads the page while a simulated capture runs. The DOM must show
// every device, progress advancing and the force plot updating; a screenshot is kept in
// build/test-artifacts/; without the token every control request gets 403 and nothing changes;
// the page's own emergency stop (with the token) aborts the session and leaves the arm stopped.
// Skipped, saying why, when chromium, node or the npm driver (scripts/setup installs it) is absent.
#include <filesystem>

#include "cli_run.h"
#include "live_support.h"
#include "sanitizer.h"

namespace hc::rig {
namespace {

using testing::LiveRig;

TEST(LivePageBrowser, ShowsTheCaptureAndObeysTheToken) {
  HC_SKIP_WHEN_SANITIZED("a real-time capture plus a browser takes minutes");
  const std::filesystem::path browser_dir = HARDCOPY_BROWSER_DIR;
  const std::filesystem::path chromium = std::getenv("CHROMIUM") ? std::getenv("CHROMIUM") : "/usr/bin/chromium";
  if (!std::filesystem::exists(chromium)) GTEST_SKIP() << "no chromium at " << chromium;
  if (hc::testing::run_command("command -v node >/dev/null").exit_code != 0)
    GTEST_SKIP() << "node is not installed";
  if (!std::filesystem::exists(browser_dir / "node_modules/playwright-core"))
    GTEST_SKIP() << "playwright-core missing: run `npm ci --prefix tests/browser` (scripts/setup does)";

  LiveRig rig;
  ASSERT_TRUE(rig.daemon->start(testing::long_press()).ok());
  ASSERT_TRUE(rig.wait_state("running"));
  const std::filesystem::path artifacts = HARDCOPY_ARTIFACTS_DIR;
  std::filesystem::create_directories(artifacts);
  const std::filesystem::path shot = artifacts / "live_page.png";
  std::filesystem::remove(shot);
  const hc::testing::CliRun run = hc::testing::run_command(
      "timeout 120 node " + (browser_dir / "live_page.mjs").string() + " " + rig.http->url() + " " +
      rig.token + " " + shot.string() + " 2>&1");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const Json r = Json::parse(run.out.substr(run.out.rfind("{\"ok\"")), nullptr, false);
  ASSERT_TRUE(r.is_object()) << run.out;
  ASSERT_TRUE(r["ok"].get<bool>()) << r.value("error", std::string());

  // Device table: one row per device of the rig, with its state.
  const Json& first = r["first"];
  EXPECT_EQ(first["devices"].size(), rig.daemon->rig().devices().size());
  for (const Json& d : first["devices"]) {
    EXPECT_FALSE(d["name"].get<std::string>().empty());
    EXPECT_FALSE(d["state"].get<std::string>().empty());
  }
  // The token from the URL is out of the address bar.
  EXPECT_EQ(first["addressBar"].get<std::string>().find("token"), std::string::npos);
  // Progress advances and the plot updates between the two looks (1.5 s apart).
  const Json& second = r["second"];
  EXPECT_EQ(second["state"], "running");
  EXPECT_GT(second["updates"].get<int>(), first["updates"].get<int>() + 5);  // pushes keep coming
  EXPECT_GE(second["done"].get<int>(), first["done"].get<int>());
  EXPECT_GT(second["plotLastT"].get<double>(), first["plotLastT"].get<double>());
  EXPECT_NE(second["plotPath"], first["plotPath"]);
  EXPECT_GT(second["plotPoints"].get<int>(), 10);
  EXPECT_NE(second["arm"], "–");
  EXPECT_EQ(second["safety"], "ok");
  ASSERT_FALSE(r["thumbnails"].empty());
  EXPECT_GT(r["thumbnails"][0]["width"].get<int>(), 0);
  EXPECT_TRUE(std::filesystem::exists(shot));
  EXPECT_GT(std::filesystem::file_size(shot), 10000u);

  // Without the token: read-only and refused.
  const Json& guest = r["guest"];
  EXPECT_NE(guest["mode"].get<std::string>().find("read-only"), std::string::npos);
  EXPECT_TRUE(guest["estopDisabled"].get<bool>());
  for (const auto& [cmd, status] : guest["statuses"].items()) EXPECT_EQ(status, 403) << cmd;
  EXPECT_EQ(guest["wrong"], 403);
  EXPECT_EQ(r["after_guest"]["state"], "running");  // nothing changed

  // The page's estop (with the token): aborted, arm stopped.
  ASSERT_TRUE(rig.daemon->wait_idle(30000));
  const Json summary = rig.daemon->last_summary();
  EXPECT_EQ(summary["state"], "aborted");
  EXPECT_EQ(summary["trip"]["kind"], "estop");
  const auto now = rig.daemon->rig().clock().now_ns();
  EXPECT_EQ(rig.daemon->rig().world()->arm_state(now).motion, devices::ArmMotion::kStopped);
}

}  // namespace
}  // namespace hc::rig
