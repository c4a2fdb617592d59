// Sessions run in-process on the embedded default rig with simulated time (deterministic, as fast
// as the CPU allows): every frame, trigger edge and force sample associates; safety trips stop the
// arm within one control cycle; replays of the same inputs give the same bytes.
#include <gtest/gtest.h>

#include <cmath>

#include "rig_daemon/daemon/daemon.h"
#include "session_support.h"
#include "test_data.h"

namespace hc::rig {
namespace {

using hc::testing::ScratchDir;
using testing::json_of;
using testing::read_session;

std::filesystem::path example(const std::string& name) {
  return hc::testing::source_dir() / "rig_daemon/examples" / name;
}

std::unique_ptr<Daemon> make_daemon(const std::filesystem::path& dir,
                                    const std::string& extra = "") {
  Result<RigConfig> cfg =
      parse_rig_config(std::string(kEmbeddedDefaultRigConfig) + extra, "rig.yaml");
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  cfg->sessions_dir = dir;
  Daemon::Options o;
  o.config = *cfg;
  o.clock = std::make_shared<devices::SimulatedClock>(1'000'000'000);
  o.software_version = "test";
  Result<std::unique_ptr<Daemon>> d = Daemon::create(o);
  EXPECT_TRUE(d.ok()) << d.status().to_string();
  return d.ok() ? std::move(d).value() : nullptr;
}

Json run_plan(Daemon& d, const Plan& plan) {
  Result<Json> started = d.start(plan);
  EXPECT_TRUE(started.ok()) << started.status().to_string();
  EXPECT_TRUE(d.wait_idle(120000));
  return d.last_summary();
}

TEST(Session, HandHeldAllAssociates) {
  ScratchDir dir;
  auto d = make_daemon(dir.path());
  ASSERT_TRUE(d);
  Result<Plan> plan = load_plan(example("hand_held_face.yaml"));
  ASSERT_TRUE(plan.ok());
  Json s = run_plan(*d, *plan);
  EXPECT_EQ(s["state"], "finished") << s.dump(2);
  const Json& a = s["association"];
  EXPECT_EQ(a["edges"], 20) << a.dump();
  EXPECT_EQ(a["edges_complete"], 20) << a.dump();
  EXPECT_EQ(a["frames"], 60);
  EXPECT_EQ(a["frames_associated"], 60);
}

}  // namespace
}  // namespace hc::rig
