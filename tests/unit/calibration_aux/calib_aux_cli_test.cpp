// `hardcopy calib ft-bias | fsr | hand-eye`: exit codes, --json contract, files written only on
// success, on a session recorded from the simulated rig (force_session_support.h).
#include <gtest/gtest.h>

#include <filesystem>

#include "calibration/force/fsr_io.h"
#include "camera/camera_model.h"
#include "cli_run.h"
#include "common/file_io.h"
#include "common/json.h"
#include "force_session_support.h"
#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::hardcopy;
using hc::testing::ScratchDir;

class CalibAuxCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir();
    const Status s = testing::record_sim_force_session(*dir_ / "force.mcap", {});
    ASSERT_TRUE(s.ok()) << s.to_string();
    ASSERT_TRUE(write_file_atomic(*dir_ / "junk.mcap", "definitely not MCAP").ok());
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string path(const std::string& name) { return (*dir_ / name).string(); }
  static ScratchDir* dir_;
};
ScratchDir* CalibAuxCli::dir_ = nullptr;

TEST_F(CalibAuxCli, FtBiasJson) {
  const auto r = hardcopy("calib ft-bias " + path("force.mcap") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  Result<Json> j = parse_json(r.out, "stdout");
  ASSERT_TRUE(j.ok()) << r.out;
  EXPECT_EQ((*j)["device"], "ft");
  // The simulated F/T's offset_n 0.4 N and drift 0.002 N/s on Fz (force_session_support.h).
  EXPECT_NEAR((*j)["bias"][2].get<double>(), 0.4, 0.01);
  EXPECT_NEAR((*j)["drift_per_s"][2].get<double>(), 0.002, 0.0005);
  for (const char* key : {"bias_std", "noise_std", "drift_total", "unloaded_intervals_s"})
    EXPECT_TRUE(j->contains(key)) << key;
  const auto text = hardcopy("calib ft-bias " + path("force.mcap"));
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.out.find("Fz  bias"), std::string::npos) << text.out;
}

TEST_F(CalibAuxCli, FsrWritesTheCalibrationFile) {
  const std::string out = path("fsr.json");
  const auto r = hardcopy("calib fsr " + path("force.mcap") + " -o " + out + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  Result<Json> j = parse_json(r.out, "stdout");
  ASSERT_TRUE(j.ok()) << r.out;
  EXPECT_EQ((*j)["model"], "power_law");
  EXPECT_LT((*j)["rms_n"].get<double>(), 0.12);
  EXPECT_LT((*j)["truth_rms_error_n"].get<double>(), 0.15);
  // The spec's FSR calibration: threshold 0.03, scale 50 N, exponent 1.4.
  Result<FsrCurve> c = read_fsr_calibration(out);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_NEAR(c->power_law.threshold, 0.03, 2e-3);
  EXPECT_NEAR(c->power_law.scale_n, 50.0, 1.0);
  EXPECT_NEAR(c->power_law.exponent, 1.4, 0.03);
  EXPECT_EQ(c->device, "fsr");
}

TEST_F(CalibAuxCli, BadInputExitsTwoAndWritesNothing) {
  const std::string out = path("never.json");
  EXPECT_EQ(hardcopy("calib fsr " + path("junk.mcap") + " -o " + out).exit_code, 2);
  EXPECT_EQ(hardcopy("calib fsr " + path("missing.mcap") + " -o " + out).exit_code, 2);
  EXPECT_EQ(hardcopy("calib ft-bias " + path("junk.mcap")).exit_code, 2);
  EXPECT_EQ(hardcopy("calib ft-bias " + path("force.mcap") + " --device nope").exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(out));
  // A session with an F/T but no FSR channel.
  ScratchDir d;
  testing::SimForceSpec spec;
  spec.record_fsr = false;
  spec.steps = 3;
  ASSERT_TRUE(testing::record_sim_force_session(d / "ft_only.mcap", spec).ok());
  EXPECT_EQ(hardcopy("calib fsr " + (d / "ft_only.mcap").string() + " -o " + out).exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(out));
  // hand-eye: unreadable calibration, a session without arm states; the output stays unwritten.
  const std::string cal = path("rig.yml");
  RigCalibration rig;
  CameraModel cam;
  cam.name = "cam0";
  cam.width = 320;
  cam.height = 240;
  cam.fx = cam.fy = 400;
  cam.cx = 159.5;
  cam.cy = 119.5;
  rig.cameras.push_back(cam);
  ASSERT_TRUE(write_rig_calibration(cal, rig).ok());
  const std::string he_out = path("he.yml");
  EXPECT_EQ(hardcopy("calib hand-eye " + path("force.mcap") + " --calib " + path("junk.mcap") +
                     " -o " + he_out)
                .exit_code,
            2);
  const auto no_arm =
      hardcopy("calib hand-eye " + path("force.mcap") + " --calib " + cal + " -o " + he_out);
  EXPECT_EQ(no_arm.exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(he_out));
  // Usage errors (CLI11) are bad input too.
  EXPECT_EQ(hardcopy("calib fsr " + path("force.mcap")).exit_code, 2);  // no -o
  EXPECT_EQ(hardcopy("calib ft-bias --help").exit_code, 0);
}

}  // namespace
}  // namespace hc::calib
