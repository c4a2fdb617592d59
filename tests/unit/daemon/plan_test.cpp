// Plans and rig configs: the shipped examples read, defaults hold, and every malformed plan is
// rejected with "FILE:LINE: key: what".
#include <gtest/gtest.h>

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>

#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig.h"
#include "rig_daemon/daemon/rig_config.h"
#include "test_data.h"

namespace hc::rig {
namespace {

TEST(Plan, ExampleAutomatedPlanReads) {
  Result<Plan> plan = load_plan(hc::testing::rig_example("automated_block.yaml"));
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_EQ(plan->protocol, Protocol::kAutomated);
  EXPECT_EQ(plan->name, "silicone_block");
  EXPECT_EQ(plan->automated.locations.size(), 2u);
  EXPECT_EQ(plan->automated.steps, 30);
  EXPECT_EQ(plan->automated.cameras.size(), 7u);  // thesis 5.6: seven Basler cameras
  // 2 locations x 2 levels x 30 steps x 1 frame per step.
  EXPECT_EQ(plan->expected_triggers(), 120);
  EXPECT_EQ(plan->specimen.at("material"), "Tango Black Plus");
  EXPECT_FALSE(plan->source_text.empty());
}

TEST(Plan, ExampleHandHeldPlanReads) {
  Result<Plan> plan = load_plan(hc::testing::rig_example("hand_held_face.yaml"));
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_EQ(plan->protocol, Protocol::kHandHeld);
  EXPECT_EQ(plan->hand_held.cameras.size(), 3u);  // thesis 4.4: trinocular system
  EXPECT_DOUBLE_EQ(plan->hand_held.trigger.rate_hz, 5.0);
  EXPECT_EQ(plan->expected_triggers(), 20);  // 5 Hz x 4 s
}

TEST(Plan, ExampleCalibrationPlanReads) {
  Result<Plan> plan = load_plan(hc::testing::rig_example("calibration_board.yaml"));
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_EQ(plan->protocol, Protocol::kCalibration);
  const CalibrationPlan& c = plan->calibration;
  EXPECT_EQ(c.board_cols, 9);
  EXPECT_EQ(c.board_rows, 6);
  EXPECT_DOUBLE_EQ(c.square_m, 0.008);
  EXPECT_EQ(c.poses, 20);
  EXPECT_EQ(c.seed, 3u);
  EXPECT_EQ(c.cameras.size(), 7u);
  EXPECT_EQ(plan->expected_triggers(), 20);  // one pulse per pose
  const Json j = plan->to_json();
  EXPECT_EQ(j["protocol"], "calibration");
  EXPECT_EQ(j["board"]["rows"], 6);
}

TEST(Plan, ExampleTrackingPlanReads) {
  Result<Plan> plan = load_plan(hc::testing::rig_example("automated_track.yaml"));
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_EQ(plan->protocol, Protocol::kAutomated);
  EXPECT_EQ(plan->automated.locations.size(), 1u);
  EXPECT_EQ(plan->expected_triggers(), 30);  // the thesis's minimum of 30 steps, one level
}

TEST(Plan, ExampleHandEyePlanReads) {
  Result<Plan> plan = load_plan(hc::testing::rig_example("hand_eye.yaml"));
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  EXPECT_EQ(plan->protocol, Protocol::kAutomated);
  const auto& l = plan->automated.locations;
  ASSERT_EQ(l.size(), 4u);
  EXPECT_EQ(plan->expected_triggers(), 120);  // 4 locations x 30 steps
  // Hand-eye needs locations that are not collinear: the first three span a triangle.
  const Eigen::Vector3d a(l[1].position_m[0] - l[0].position_m[0],
                          l[1].position_m[1] - l[0].position_m[1],
                          l[1].position_m[2] - l[0].position_m[2]);
  const Eigen::Vector3d b(l[2].position_m[0] - l[0].position_m[0],
                          l[2].position_m[1] - l[0].position_m[1],
                          l[2].position_m[2] - l[0].position_m[2]);
  EXPECT_GT(a.cross(b).norm(), 1e-4);  // m^2: 20 mm x 20 mm
}

TEST(Plan, DirectionIsNormalised) {
  Result<Plan> plan = parse_plan(R"(protocol: automated
locations: [{position_m: [0, 0, 0.05], direction: [0, 3, -4]}]
force_levels_n: [10]
steps: 30
max_force_n: 20
workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}
)",
                                 "p.yaml");
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  // (0, 3, -4) / 5, exact in binary to within one ulp.
  EXPECT_NEAR(plan->automated.locations[0].direction[1], 0.6, 1e-15);
  EXPECT_NEAR(plan->automated.locations[0].direction[2], -0.8, 1e-15);
}

struct BadPlan {
  const char* name;
  const char* yaml;
  const char* expected;  // substring of the message
};

class BadPlans : public ::testing::TestWithParam<BadPlan> {};

TEST_P(BadPlans, AreRejectedWithFileLineAndKey) {
  Result<Plan> plan = parse_plan(GetParam().yaml, "bad.yaml");
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(plan.status().message().find(GetParam().expected), std::string::npos)
      << plan.status().message();
  EXPECT_EQ(plan.status().message().rfind("bad.yaml:", 0), 0u) << plan.status().message();
}

constexpr const char* kAutoTail = R"(
force_levels_n: [10]
max_force_n: 20
workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}
locations: [{position_m: [0, 0, 0.05]}]
)";

const std::string kTooFew = std::string("protocol: automated\nsteps: 29") + kAutoTail;
const std::string kTooMany = std::string("protocol: automated\nsteps: 201") + kAutoTail;

INSTANTIATE_TEST_SUITE_P(
    Plan, BadPlans,
    ::testing::Values(
        BadPlan{"no_protocol", "name: x\n", "bad.yaml:1: protocol: required key is missing"},
        BadPlan{"unknown_protocol", "protocol: robotic\n", "bad.yaml:1: protocol: expected one of"},
        BadPlan{"steps_too_few", kTooFew.c_str(),
                "bad.yaml:2: steps: expected an integer in [30, 200]"},
        BadPlan{"steps_too_many", kTooMany.c_str(), "steps: expected an integer in [30, 200]"},
        BadPlan{"rate_zero",
                "protocol: hand_held\ntrigger: {rate_hz: 0}\nduration_s: 1\ncameras: [c]\n",
                "bad.yaml:2: trigger.rate_hz: expected a number in (0, 1000]"},
        BadPlan{"rate_text",
                "protocol: hand_held\ntrigger: {rate_hz: fast}\nduration_s: 1\ncameras: [c]\n",
                "trigger.rate_hz: expected a number"},
        BadPlan{"pulse_too_long",
                "protocol: hand_held\ntrigger: {rate_hz: 100, pulse_width_s: 0.02}\n"
                "duration_s: 1\ncameras: [c]\n",
                "pulse_width_s must be shorter than the trigger period"},
        BadPlan{"typo_key",
                "protocol: hand_held\ntrigger: {rate_hz: 1}\nduration_s: 1\ncameras: [c]\n"
                "duraton_s: 2\n",
                "bad.yaml:5: unknown key 'duraton_s'"},
        BadPlan{"level_over_max",
                "protocol: automated\nsteps: 30\nforce_levels_n: [10, 30]\nmax_force_n: 20\n"
                "workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}\n"
                "locations: [{position_m: [0, 0, 0.05]}]\n",
                "bad.yaml:3: force_levels_n: every level must be at most max_force_n"},
        BadPlan{"force_over_sensor",
                "protocol: automated\nsteps: 30\nforce_levels_n: [10]\nmax_force_n: 200\n"
                "workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}\n"
                "locations: [{position_m: [0, 0, 0.05]}]\n",
                "bad.yaml:4: max_force_n: expected a number in (0, 125]"},
        BadPlan{"outside_workspace",
                "protocol: automated\nsteps: 30\nforce_levels_n: [10]\nmax_force_n: 20\n"
                "workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}\n"
                "locations:\n  - {position_m: [0, 0, 0.05]}\n  - {position_m: [0, 0, 1.5]}\n",
                "bad.yaml:8: locations[1].position_m: outside the plan's workspace box"},
        BadPlan{"inverted_box",
                "protocol: automated\nsteps: 30\nforce_levels_n: [10]\nmax_force_n: 20\n"
                "workspace: {min_m: [-1, -1, 1], max_m: [1, 1, 0]}\n"
                "locations: [{position_m: [0, 0, 0.05]}]\n",
                "bad.yaml:5: workspace: max_m.z must be greater than min_m.z"},
        BadPlan{"zero_direction",
                "protocol: automated\nsteps: 30\nforce_levels_n: [10]\nmax_force_n: 20\n"
                "workspace: {min_m: [-1, -1, 0], max_m: [1, 1, 1]}\n"
                "locations: [{position_m: [0, 0, 0.05], direction: [0, 0, 0]}]\n",
                "locations[0].direction: expected a non-zero vector"},
        BadPlan{"bad_name", "protocol: hand_held\nname: ../etc\n", "name: expected 1-128"},
        BadPlan{"calibration_no_board", "protocol: calibration\nposes: 10\ncameras: [c]\n",
                "bad.yaml:1: board: required"},
        BadPlan{"calibration_no_poses",
                "protocol: calibration\nboard: {cols: 9, rows: 6, square_m: 0.01}\ncameras: [c]\n",
                "bad.yaml:1: poses: required key is missing"},
        BadPlan{"calibration_tiny_board",
                "protocol: calibration\nboard: {cols: 1, rows: 6, square_m: 0.01}\nposes: 5\n"
                "cameras: [c]\n",
                "bad.yaml:2: board.cols: expected an integer in [2, 64]"},
        BadPlan{"calibration_square_zero",
                "protocol: calibration\nboard: {cols: 9, rows: 6, square_m: 0}\nposes: 5\n"
                "cameras: [c]\n",
                "board.square_m: expected a number in (0, 1]"},
        BadPlan{"calibration_no_cameras",
                "protocol: calibration\nboard: {cols: 9, rows: 6, square_m: 0.01}\nposes: 5\n"
                "cameras: []\n",
                "cameras: expected at least one camera"},
        BadPlan{"calibration_too_many_poses",
                "protocol: calibration\nboard: {cols: 9, rows: 6, square_m: 0.01}\nposes: 5000\n"
                "cameras: [c]\n",
                "bad.yaml:3: poses: expected an integer in [1, 1000]"},
        BadPlan{"not_yaml", "protocol: [hand_held\n", "invalid YAML"}),
    [](const ::testing::TestParamInfo<BadPlan>& p) { return std::string(p.param.name); });

TEST(RigConfig, EmbeddedDefaultIsAllSimulated) {
  Result<RigConfig> rig = embedded_default_rig_config();
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  EXPECT_EQ(rig->devices.size(), 11u);
  for (const DeviceConfig& d : rig->devices) EXPECT_EQ(d.backend, "sim") << d.name;
  EXPECT_EQ(rig->sessions_dir, std::filesystem::path("./sessions"));
  EXPECT_EQ(default_socket_path(*rig), std::filesystem::path("./sessions/rigd.sock"));
  ASSERT_NE(rig->first(DeviceKind::kArm), nullptr);
  EXPECT_EQ(rig->first(DeviceKind::kArm)->name, "arm");
}

TEST(RigConfig, ExampleMatchesEmbeddedDefault) {
  Result<RigConfig> example_rig = load_rig_config(hc::testing::rig_example("rig_sim.yaml"));
  ASSERT_TRUE(example_rig.ok()) << example_rig.status().to_string();
  Result<RigConfig> def = embedded_default_rig_config();
  ASSERT_TRUE(def.ok());
  Json a = example_rig->to_json(), b = def->to_json();
  a.erase("source");
  b.erase("source");
  EXPECT_EQ(a, b);
}

TEST(RigConfig, BadConfigsNameTheKey) {
  const struct {
    const char* yaml;
    const char* expected;
  } cases[] = {
      {"workspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\n",
       "rig.yaml:1: devices: expected a map of devices"},
      {"devices:\n  cam0: {kind: webcam, backend: sim}\n"
       "workspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\n",
       "rig.yaml:2: devices.cam0.kind: expected one of"},
      {"devices:\n  cam0: {kind: camera}\nworkspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\n",
       "rig.yaml:2: devices.cam0.backend: required key is missing"},
      {"devices:\n  arm: {kind: arm, backend: sim}\n"
       "workspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\nmax_force_n: -3\n",
       "rig.yaml:4: max_force_n: expected a number in (0, 125]"},
      {"devices:\n  arm: {kind: arm, backend: sim}\n"
       "workspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\ncompression: gzip\n",
       "rig.yaml:4: compression: expected one of"},
      {"devices:\n  arm: {kind: arm, backend: sim}\n"
       "workspace: {min_m: [0, 0, 0], max_m: [1, 1, 1]}\ncontrol_period_s: 0.01\n"
       "stall_timeout_s: 0.005\n",
       "stall_timeout_s: must be at least control_period_s"},
  };
  for (const auto& c : cases) {
    Result<RigConfig> rig = parse_rig_config(c.yaml, "rig.yaml");
    ASSERT_FALSE(rig.ok()) << c.yaml;
    EXPECT_NE(rig.status().message().find(c.expected), std::string::npos) << rig.status().message();
  }
}

TEST(Workspace, ContainsAndIntersect) {
  WorkspaceBox a{{0, 0, 0}, {1, 1, 1}}, b{{0.5, -1, 0.2}, {2, 0.5, 0.8}};
  const WorkspaceBox c = a.intersect(b);
  EXPECT_EQ(c.min_m, (std::array<double, 3>{0.5, 0, 0.2}));
  EXPECT_EQ(c.max_m, (std::array<double, 3>{1, 0.5, 0.8}));
  EXPECT_TRUE(c.contains({0.7, 0.1, 0.5}));
  EXPECT_FALSE(c.contains({0.4, 0.1, 0.5}));
  EXPECT_TRUE(a.intersect(WorkspaceBox{{2, 2, 2}, {3, 3, 3}}).empty());
}

}  // namespace
}  // namespace hc::rig

namespace hc::rig {
namespace {

TEST(RigConfig, HighResolutionExampleRigSeesTheWholeSpecimen) {
  // rig_sim_hires.yaml: seven 1600 x 1200 cameras on a half circle (thesis 5.6). At rest every
  // one of the specimen's 441 markers (21 x 21, 3 mm grid over 60 mm) is in every camera's view,
  // each dot is several pixels wide, and the specimen spans a good part of the image.
  Result<RigConfig> cfg = load_rig_config(hc::testing::rig_example("rig_sim_hires.yaml"));
  ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
  Rig::Options o;
  o.config = *cfg;
  o.clock = std::make_shared<devices::SimulatedClock>(1'000'000'000);
  Result<std::unique_ptr<Rig>> rig = Rig::create(o);
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  devices::sim::World& world = *(*rig)->world();
  const std::vector<devices::sim::CameraRecord> cams = world.cameras();
  ASSERT_EQ(cams.size(), 7u);
  const devices::sim::GroundTruth g = world.ground_truth(world.clock().now_ns());
  ASSERT_EQ(g.markers_m.size(), 441u);
  ASSERT_EQ(g.cameras.size(), 7u);
  for (std::size_t i = 0; i < 7; ++i) {
    const CameraModel& c = cams[i].camera;
    EXPECT_EQ(c.width, 1600u);
    EXPECT_EQ(c.height, 1200u);
    EXPECT_TRUE(g.cameras[i].out_of_view.empty()) << cams[i].name;
    double u0 = 1e9, u1 = -1e9, v0 = 1e9, v1 = -1e9;
    for (const Eigen::Vector3d& m : g.markers_m) {
      const Eigen::Vector2d uv = *c.project(m);
      u0 = std::min(u0, uv.x()), u1 = std::max(u1, uv.x());
      v0 = std::min(v0, uv.y()), v1 = std::max(v1, uv.y());
    }
    EXPECT_GT(std::max(u1 - u0, v1 - v0), 600.0) << cams[i].name;
    // Dot radius f r / D with r = 0.6 mm, D ~ 0.3 m: ~7 px.
    EXPECT_GT(c.fx * 0.0006 / c.depth_m(g.markers_m[220]), 6.0);
  }
  // The example calibration plan suits this rig too: every board pose is seen whole by at least
  // two cameras (so the joint adjustment links them), some only by a subset.
  Result<Plan> plan = load_plan(hc::testing::rig_example("calibration_board.yaml"));
  ASSERT_TRUE(plan.ok());
  devices::sim::BoardSpec spec;
  spec.cols = plan->calibration.board_cols;
  spec.rows = plan->calibration.board_rows;
  spec.square_m = plan->calibration.square_m;
  devices::sim::BoardMotion motion;
  motion.poses = plan->calibration.poses;
  motion.seed = plan->calibration.seed;
  motion.max_tilt_deg = plan->calibration.max_tilt_deg;
  int subset = 0;
  for (const devices::sim::BoardPose& p :
       devices::sim::board_poses(spec, motion, Eigen::Vector3d(0.0, 0.0, 0.05))) {
    int seen = 0;
    for (const devices::sim::CameraRecord& r : cams)
      seen += devices::sim::board_visible(r.camera, spec, p) ? 1 : 0;
    EXPECT_GE(seen, 2);
    subset += seen < 7 ? 1 : 0;
  }
  EXPECT_GE(subset, 2);
}

}  // namespace
}  // namespace hc::rig
