// `hardcopy calib cameras`: the CLI contract of issue 5 (--images per camera, --session, --json
// keys, exit codes, nothing written on bad input).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>

#include "calibration/cameras/board.h"
#include "calibration/cameras/synthetic.h"
#include "camera/camera_model.h"
#include "cli_run.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::hardcopy;
using hc::testing::ScratchDir;
using hc::testing::shared_data;

std::string stereo_dir() { return shared_data("calibration/opencv_stereo").string(); }

TEST(CalibCli, StereoImagesJson) {
  ScratchDir dir;
  const auto out = dir / "stereo.yml";
  const auto r =
      hardcopy("calib cameras --pattern chessboard:9x6:0.025 --images 'left=" + stereo_dir() +
               "/left*.jpg' --images 'right=" + stereo_dir() +
               "/right*.jpg' --fix-aspect-ratio -o " + out.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  for (const char* cam : {"left", "right"}) {
    ASSERT_TRUE(j["cameras"].contains(cam));
    for (const char* key : {"rms_px", "fx", "fy", "cx", "cy", "distortion", "R", "t_m"})
      EXPECT_TRUE(j["cameras"][cam].contains(key)) << cam << " " << key;
    EXPECT_EQ(j["cameras"][cam]["R"].size(), 3u);
    EXPECT_EQ(j["cameras"][cam]["distortion"].size(), 5u);
  }
  // OpenCV 4.6 stereo_calib: 0.634183 px (reference_runs_opencv460/stereo_calib.out.txt).
  EXPECT_LE(j["joint_rms_px"].get<double>(), 0.634183);
  EXPECT_TRUE(j["converged"].get<bool>()) << j["termination"];
  const std::vector<double> t = j["cameras"]["right"]["t_m"];
  EXPECT_NEAR(std::hypot(t[0], t[1], t[2]), 3.343 * 0.025, 0.005 * 3.343 * 0.025);
  EXPECT_EQ(j["cameras"]["left"]["t_m"], nlohmann::json({0.0, 0.0, 0.0}));
  EXPECT_TRUE(j.contains("time_s"));
  EXPECT_TRUE(j["views"].is_array());
  EXPECT_EQ(j["views"].size(), 26u);
  ASSERT_FALSE(j["outlier_views"].empty());  // view 2 (MANIFEST.md: left02 is the outlier)
  EXPECT_EQ(j["outlier_views"][0]["view"], 2);
  EXPECT_TRUE(j["cameras"]["left"].contains("std"));
  // The file holds the same numbers.
  Result<RigCalibration> rig = read_rig_calibration(out);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  ASSERT_EQ(rig->cameras.size(), 2u);
  EXPECT_DOUBLE_EQ(rig->cameras[1].fx, j["cameras"]["right"]["fx"].get<double>());
  EXPECT_NEAR(rig->joint_rms_px, j["joint_rms_px"].get<double>(), 1e-12);
}

TEST(CalibCli, SingleCameraNoJointRms) {
  ScratchDir dir;
  const auto r =
      hardcopy("calib cameras --pattern chessboard:9x6:0.025 --images 'left=" + stereo_dir() +
               "/left*.jpg' --fix-aspect-ratio -o " + (dir / "l.yml").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j.contains("joint_rms_px"));
  // reference_runs_opencv460/mono_ref.out.txt: RMS 0.408787, fx 536.1087.
  EXPECT_NEAR(j["cameras"]["left"]["rms_px"].get<double>(), 0.408787, 0.02);
  EXPECT_NEAR(j["cameras"]["left"]["fx"].get<double>(), 536.1087, 0.002 * 536.1087);
}

TEST(CalibCli, BadInput) {
  ScratchDir dir;
  const auto out = dir / "out.yml";
  const std::string o = " -o " + out.string();
  // Unreadable image.
  std::ofstream(dir / "left01.jpg") << "not a jpeg";
  EXPECT_EQ(hardcopy("calib cameras --pattern chessboard:9x6:0.025 --images 'left=" +
                     (dir / "left*.jpg").string() + "'" + o)
                .exit_code,
            2);
  // No board found (a blank image).
  cv::imwrite((dir / "blank05.png").string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(128)));
  const auto no_board = hc::testing::run_command(
      (hc::testing::bin_dir() / "hardcopy").string() +
      " --quiet calib cameras --pattern chessboard:9x6:0.025 --images 'c=" +
      (dir / "blank*.png").string() + "'" + o + " 2>&1");
  EXPECT_EQ(no_board.exit_code, 2);
  EXPECT_NE(no_board.out.find("no board found"), std::string::npos) << no_board.out;
  // Glob matching nothing, bad pattern, bad camera name, both / neither sources.
  EXPECT_EQ(
      hardcopy("calib cameras --pattern chessboard:9x6:0.025 --images 'c=/nonexistent/*.png'" + o)
          .exit_code,
      2);
  EXPECT_EQ(hardcopy("calib cameras --pattern chessboard:9y6:0.025 --images 'left=" + stereo_dir() +
                     "/left*.jpg'" + o)
                .exit_code,
            2);
  EXPECT_EQ(hardcopy("calib cameras --pattern chessboard:9x6:0.025 --images '9 x=" + stereo_dir() +
                     "/left*.jpg'" + o)
                .exit_code,
            2);
  EXPECT_EQ(hardcopy("calib cameras --pattern chessboard:9x6:0.025" + o).exit_code, 2);
  // Session with no camera channel.
  {
    auto w = recording::McapWriter::open(dir / "nocam.mcap", {});
    ASSERT_TRUE(w.ok());
    auto ch = (*w)->add_channel("/ft/wrench", "json", 0, {{"kind", "force_torque"}});
    ASSERT_TRUE(ch.ok());
    const recording::Bytes msg = recording::json_message(Json{{"fx", 1.0}});
    ASSERT_TRUE((*w)->write_message(*ch, 1, 1, msg).ok());
    ASSERT_TRUE((*w)->close().ok());
  }
  const auto nocam =
      hc::testing::run_command((hc::testing::bin_dir() / "hardcopy").string() +
                               " --quiet calib cameras --pattern chessboard:9x6:0.025 --session " +
                               (dir / "nocam.mcap").string() + o + " 2>&1");
  EXPECT_EQ(nocam.exit_code, 2);
  EXPECT_NE(nocam.out.find("no camera channel"), std::string::npos) << nocam.out;
  EXPECT_EQ(hardcopy("calib cameras --pattern chessboard:9x6:0.025 --session " +
                     (dir / "missing.mcap").string() + o)
                .exit_code,
            2);
  EXPECT_FALSE(std::filesystem::exists(out));
}

// A session written with the recording library like rigd does (channel metadata kind=camera,
// foxglove.RawImage frames, /session/sync grouping frames by trigger index; the two cameras'
// frame sequences differ so only the sync records pair them), holding rendered board images of a
// known 2-camera rig.
TEST(CalibCli, SessionRecoversKnownRig) {
  ScratchDir dir;
  const BoardSpec board = *parse_board_spec("chessboard:9x6:0.05");
  SyntheticRigOptions ro;
  ro.cameras = 2;
  ro.arc_deg = 35.0;
  ro.width = 640;
  ro.height = 480;
  ro.focal_px = 640.0;
  const std::vector<CameraModel> truth = make_half_circle_rig(ro);
  const auto poses = random_board_poses(truth, board, 10, 1234, 2, 0.08, 30.0);
  ASSERT_EQ(poses.size(), 10u);
  {
    auto w = recording::McapWriter::open(dir / "s.mcap", {});
    ASSERT_TRUE(w.ok());
    auto schema =
        (*w)->add_schema(recording::kRawImageSchemaName, "protobuf", recording::raw_image_schema());
    ASSERT_TRUE(schema.ok());
    std::vector<std::uint16_t> ch;
    for (const CameraModel& c : truth) {
      auto id = (*w)->add_channel("/" + c.name + "/image", "protobuf", *schema,
                                  {{"device", c.name}, {"kind", "camera"}, {"backend", "sim"}});
      ASSERT_TRUE(id.ok());
      ch.push_back(*id);
    }
    auto sync = (*w)->add_channel("/session/sync", "json", 0, {{"device", "session"}});
    ASSERT_TRUE(sync.ok());
    std::vector<ChessboardRenderer> renderers;
    for (const CameraModel& c : truth) renderers.emplace_back(c, board);
    for (std::size_t k = 0; k < poses.size(); ++k) {
      std::map<std::string, std::uint64_t> frames;
      for (std::size_t c = 0; c < truth.size(); ++c) {
        const std::uint32_t seq = static_cast<std::uint32_t>(100 * (c + 1) + 3 * k);
        recording::RawImage img;
        img.timestamp_ns = static_cast<std::int64_t>(k) * 1000000;
        img.frame_id = truth[c].name;
        img.width = static_cast<std::uint32_t>(truth[c].width);
        img.height = static_cast<std::uint32_t>(truth[c].height);
        img.encoding = "mono8";
        img.step = img.width;
        img.data = renderers[c].render(poses[k]);
        recording::Bytes msg;
        recording::encode_raw_image(img, msg);
        ASSERT_TRUE((*w)->write_message(ch[c], k * 1000 + c, k * 1000 + c, msg, seq).ok());
        frames[truth[c].name] = seq;
      }
      session::SyncRecord record;
      record.trigger_index = static_cast<std::uint64_t>(k + 7);
      record.frames = frames;
      const std::string text = session::to_json(record);
      const recording::Bytes s(text.begin(), text.end());
      ASSERT_TRUE((*w)->write_message(*sync, k * 1000 + 5, k * 1000 + 5, s).ok());
    }
    ASSERT_TRUE((*w)->close().ok());
  }
  const auto out = dir / "rig.yml";
  const auto r = hardcopy("calib cameras --pattern chessboard:9x6:0.05 --session " +
                          (dir / "s.mcap").string() + " -o " + out.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["board_poses"], 10);
  Result<RigCalibration> rig = read_rig_calibration(out);
  ASSERT_TRUE(rig.ok());
  ASSERT_EQ(rig->cameras.size(), 2u);
  for (std::size_t c = 0; c < 2; ++c) {
    const CameraModel& g = *rig->find(truth[c].name);
    EXPECT_NEAR(g.fx, truth[c].fx, 0.002 * truth[c].fx) << g.name;
    EXPECT_NEAR(g.fy, truth[c].fy, 0.002 * truth[c].fy) << g.name;
    EXPECT_LT((g.center_m() - truth[c].center_m()).norm(), 2e-3) << g.name;
  }
  EXPECT_LT(j["joint_rms_px"].get<double>(), 0.15);
}

}  // namespace
}  // namespace hc::calib
