// The camera model and the rig calibration file (camera/camera_model.h).
#include "camera/camera_model.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>
#include <fstream>
#include <string>

#include "common/file_io.h"
#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::ScratchDir;

CameraModel make_camera(const std::string& name, std::vector<double> dist, double angle,
                        const Eigen::Vector3d& t) {
  CameraModel c;
  c.name = name;
  c.width = 1600;
  c.height = 1200;
  c.fx = 1812.5;
  c.fy = 1809.25;
  c.cx = 801.3;
  c.cy = 598.7;
  c.distortion = std::move(dist);
  c.R = Eigen::AngleAxisd(angle, Eigen::Vector3d(0.2, 1.0, -0.1).normalized()).toRotationMatrix();
  c.t_m = t;
  c.rms_px = 0.173;
  return c;
}

RigCalibration make_rig() {
  RigCalibration rig;
  rig.cameras.push_back(
      make_camera("cam0", {-0.21, 0.13, 0.0011, -0.0007, -0.02}, 0.0, Eigen::Vector3d::Zero()));
  rig.cameras.push_back(make_camera("cam_1", {-0.1, 0.05, 0.0, 0.0, 0.01, 0.001, 0.002, 0.003}, 0.7,
                                    Eigen::Vector3d(-0.31, 0.01, 0.12)));
  rig.cameras.push_back(make_camera("right-2", {}, -0.4, Eigen::Vector3d(0.25, -0.02, 0.05)));
  rig.joint_rms_px = 0.21;
  rig.world_from_rig.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  rig.world_from_rig.translation() = Eigen::Vector3d(0.1, -0.2, 0.9);
  return rig;
}

TEST(CameraModelFile, RoundTrip) {
  ScratchDir dir;
  const RigCalibration rig = make_rig();
  ASSERT_TRUE(write_rig_calibration(dir / "rig.yml", rig).ok());
  Result<RigCalibration> back = read_rig_calibration(dir / "rig.yml");
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->cameras.size(), rig.cameras.size());
  EXPECT_DOUBLE_EQ(back->joint_rms_px, rig.joint_rms_px);
  EXPECT_LT((back->world_from_rig.matrix() - rig.world_from_rig.matrix()).norm(), 1e-14);
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraModel& a = rig.cameras[i];
    const CameraModel& b = back->cameras[i];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    // FileStorage writes doubles with 16 significant digits.
    EXPECT_NEAR(a.fx, b.fx, 1e-12 * a.fx);
    EXPECT_NEAR(a.fy, b.fy, 1e-12 * a.fy);
    EXPECT_NEAR(a.cx, b.cx, 1e-12 * a.cx);
    EXPECT_NEAR(a.cy, b.cy, 1e-12 * a.cy);
    ASSERT_EQ(a.distortion.size(), b.distortion.size());
    for (std::size_t k = 0; k < a.distortion.size(); ++k)
      EXPECT_NEAR(a.distortion[k], b.distortion[k], 1e-15);
    EXPECT_LT((a.R - b.R).norm(), 1e-14);
    EXPECT_LT((a.t_m - b.t_m).norm(), 1e-15);
    EXPECT_DOUBLE_EQ(a.rms_px, b.rms_px);
  }
  EXPECT_NE(back->find("cam_1"), nullptr);
  EXPECT_EQ(back->find("nope"), nullptr);
}

// OpenCV's own FileStorage reads what we write (the contract with OpenCV-based tools).
TEST(CameraModelFile, OpenCvFileStorageReadsIt) {
  ScratchDir dir;
  const RigCalibration rig = make_rig();
  ASSERT_TRUE(write_rig_calibration(dir / "rig.yml", rig).ok());
  cv::FileStorage fs((dir / "rig.yml").string(), cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat K, d, R, t;
  fs["cam0"]["camera_matrix"] >> K;
  fs["cam_1"]["distortion_coefficients"] >> d;
  fs["cam_1"]["R"] >> R;
  fs["cam_1"]["t"] >> t;
  ASSERT_EQ(K.rows, 3);
  ASSERT_EQ(K.cols, 3);
  EXPECT_DOUBLE_EQ(K.at<double>(0, 0), 1812.5);
  EXPECT_DOUBLE_EQ(K.at<double>(1, 1), 1809.25);
  EXPECT_DOUBLE_EQ(K.at<double>(0, 2), 801.3);
  EXPECT_DOUBLE_EQ(K.at<double>(1, 2), 598.7);
  EXPECT_DOUBLE_EQ(K.at<double>(2, 2), 1.0);
  ASSERT_EQ(d.total(), 8u);
  EXPECT_DOUBLE_EQ(d.at<double>(7), 0.003);
  ASSERT_EQ(R.rows, 3);
  EXPECT_NEAR(R.at<double>(1, 2), rig.cameras[1].R(1, 2), 1e-15);
  ASSERT_EQ(t.rows, 3);
  EXPECT_DOUBLE_EQ(t.at<double>(0), -0.31);
  EXPECT_EQ(static_cast<int>(fs["cam0"]["image_width"]), 1600);
  std::vector<std::string> names;
  fs["camera_names"] >> names;
  EXPECT_EQ(names, (std::vector<std::string>{"cam0", "cam_1", "right-2"}));
}

// A file written by OpenCV itself in our layout (its matrix output, not ours) is read.
TEST(CameraModelFile, ReadsFileWrittenByOpenCv) {
  ScratchDir dir;
  {
    cv::FileStorage fs((dir / "cv.yml").string(), cv::FileStorage::WRITE);
    fs << "camera_names" << std::vector<std::string>{"left"};
    fs << "left"
       << "{";
    fs << "image_width" << 640 << "image_height" << 480;
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << 536.1, 0, 342.4, 0, 536.1, 235.6, 0, 0, 1);
    fs << "distortion_coefficients"
       << (cv::Mat_<double>(1, 5) << -0.265, -0.045, 0.0018, -0.0003, 0.25);
    fs << "R" << cv::Mat::eye(3, 3, CV_64F) << "t" << cv::Mat::zeros(3, 1, CV_64F);
    fs << "}";
  }
  Result<RigCalibration> rig = read_rig_calibration(dir / "cv.yml");
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  ASSERT_EQ(rig->cameras.size(), 1u);
  EXPECT_DOUBLE_EQ(rig->cameras[0].fx, 536.1);
  EXPECT_DOUBLE_EQ(rig->cameras[0].distortion[4], 0.25);
  EXPECT_EQ(rig->joint_rms_px, 0.0);
  EXPECT_TRUE(rig->world_from_rig.matrix().isIdentity());
}

TEST(CameraModel, ProjectUndistortInverse) {
  // Strong barrel (5 coefficients) and the rational model (8): every pixel of a grid over the
  // image goes pixel -> normalised -> pixel within 1e-9 px, and through ray_rig/project too.
  for (const CameraModel& c :
       {make_camera("a", {-0.28, 0.09, 0.0012, -0.0004, -0.012}, 0.3, {0.1, 0.0, 0.02}),
        make_camera("b", {0.4, -0.2, 0.001, 0.002, 0.05, 0.5, -0.1, 0.02}, -0.2, {0, 0.1, 0}),
        make_camera("c", {}, 0.0, {0, 0, 0})}) {
    double worst = 0.0, worst_ray = 0.0;
    for (int y = 0; y <= 1200; y += 40)
      for (int x = 0; x <= 1600; x += 40) {
        const Eigen::Vector2d px(x - 0.5, y - 0.5);
        const Eigen::Vector2d n = c.undistort_to_normalized(px);
        worst = std::max(worst, (c.distort_normalized(n) - px).norm());
        const Eigen::Vector3d X = c.center_m() + 2.5 * c.ray_rig(px);
        const auto p = c.project(X);
        ASSERT_TRUE(p.has_value());
        worst_ray = std::max(worst_ray, (*p - px).norm());
      }
    EXPECT_LT(worst, 1e-9) << c.name;
    EXPECT_LT(worst_ray, 1e-9) << c.name;
  }
}

TEST(CameraModel, ProjectionMatchesHandComputation) {
  // No distortion: project = K (R X + t) / z, the 3x4 projection matrix agrees.
  CameraModel c = make_camera("p", {}, 0.5, {0.1, -0.2, 0.3});
  const Eigen::Vector3d X(0.05, 0.02, 1.4);
  const Eigen::Vector3d xc = c.R * X + c.t_m;
  const Eigen::Vector2d expect(c.fx * xc.x() / xc.z() + c.cx, c.fy * xc.y() / xc.z() + c.cy);
  ASSERT_TRUE(c.project(X).has_value());
  EXPECT_LT((*c.project(X) - expect).norm(), 1e-9);
  const Eigen::Vector3d h = c.projection() * X.homogeneous();
  EXPECT_LT((h.hnormalized() - expect).norm(), 1e-9);
  EXPECT_FALSE(c.project(c.center_m() - c.R.transpose().col(2)).has_value());  // behind
}

// Malformed files: every case is kInvalidArgument naming the file and the key.
class MalformedFile : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(write_rig_calibration(dir_ / "good.yml", make_rig()).ok());
    Result<std::string> t = read_file(dir_ / "good.yml");
    ASSERT_TRUE(t.ok());
    good_ = *t;
  }
  // Replaces the first occurrence of `from` (must exist) and reads the result.
  Status read_mutated(const std::string& from, const std::string& to) {
    std::string text = good_;
    const auto p = text.find(from);
    EXPECT_NE(p, std::string::npos) << from << "\n" << good_;
    if (p != std::string::npos) text.replace(p, from.size(), to);
    return read_text(text);
  }
  Status read_text(const std::string& text) {
    const auto path = dir_ / "bad.yml";
    std::ofstream(path, std::ios::binary) << text;
    return read_rig_calibration(path).status();
  }
  void expect_error(const Status& s, const std::string& key) {
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.message();
    EXPECT_NE(s.message().find((dir_ / "bad.yml").string()), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(key), std::string::npos)
        << "want '" << key << "' in: " << s.message();
  }
  ScratchDir dir_;
  std::string good_;
};

TEST_F(MalformedFile, GoodFileReads) { EXPECT_TRUE(read_text(good_).ok()); }

TEST_F(MalformedFile, MissingKeys) {
  expect_error(read_mutated("camera_names:", "camera_nam:"), "camera_names");
  expect_error(read_mutated("camera_matrix:", "camera_matrx:"), "camera_matrix");
  expect_error(read_mutated("distortion_coefficients:", "distortion:"), "distortion_coefficients");
  expect_error(read_mutated("image_width:", "image_w:"), "image_width");
  expect_error(read_mutated("\n   t: ", "\n   tt: "), "'t'");
  expect_error(read_mutated("\ncam_1:", "\ncam_9:"), "cam_1");
}

TEST_F(MalformedFile, WrongMatrixSizes) {
  // camera_matrix declared 3x2 with 6 values.
  const auto p = good_.find("camera_matrix:");
  std::string text = good_;
  const auto rows = text.find("rows: 3", p);
  const auto cols = text.find("cols: 3", p);
  ASSERT_NE(cols, std::string::npos);
  text.replace(cols, 7, "cols: 2");
  const auto data = text.find("data: [", p);
  const auto end = text.find(']', data);
  text.replace(data, end - data + 1, "data: [ 1., 0., 2., 0., 1., 1. ]");
  (void)rows;
  expect_error(read_text(text), "camera_matrix");
  // R as 2x2.
  std::string text2 = good_;
  const auto rp = text2.find("\n   R: ");
  ASSERT_NE(rp, std::string::npos);
  const auto r_rows = text2.find("rows: 3", rp);
  const auto r_cols = text2.find("cols: 3", rp);
  text2.replace(r_cols, 7, "cols: 2");
  text2.replace(r_rows, 7, "rows: 2");
  const auto rd = text2.find("data: [", rp);
  const auto re = text2.find(']', rd);
  text2.replace(rd, re - rd + 1, "data: [ 1., 0., 0., 1. ]");
  expect_error(read_text(text2), "'R'");
  // Six distortion coefficients.
  std::string text3 = good_;
  const auto dp = text3.find("distortion_coefficients:");
  const auto dc = text3.find("cols: 5", dp);
  text3.replace(dc, 7, "cols: 6");
  const auto dd = text3.find("data: [", dp);
  text3.insert(dd + 7, " 0.0,");
  expect_error(read_text(text3), "distortion");
}

TEST_F(MalformedFile, NotFinite) {
  expect_error(read_mutated("joint_rms_px: ", "joint_rms_px: .nan\nx_: "), "joint_rms_px");
  const auto p = good_.find("camera_matrix:");
  const auto d = good_.find("data: [", p);
  std::string text = good_;
  text.replace(d, 8, "data: [ .nan,");
  // the first value is replaced by NaN, the old first value follows: fix the count by removing it
  const auto comma = text.find(',', d + 13);
  text.erase(d + 13, comma - (d + 13) + 1);
  expect_error(read_text(text), "camera_matrix");
}

TEST_F(MalformedFile, NotARotation) {
  // cam0's R is the identity: make it a reflection (det -1) and a scaling.
  const auto p = good_.find("\n   R: ");
  const auto d = good_.find("data: [", p);
  const auto e = good_.find(']', d);
  std::string text = good_;
  text.replace(d, e - d + 1, "data: [ 1., 0., 0., 0., 1., 0., 0., 0., -1. ]");
  expect_error(read_text(text), "rotation");
  text = good_;
  text.replace(d, e - d + 1, "data: [ 2., 0., 0., 0., 2., 0., 0., 0., 2. ]");
  expect_error(read_text(text), "rotation");
}

TEST_F(MalformedFile, RepeatedOrEmptyNames) {
  expect_error(read_mutated("   - cam_1\n", "   - cam0\n"), "cam0");
  expect_error(read_mutated("   - cam_1\n", "   - \"\"\n"), "camera name");
}

TEST_F(MalformedFile, NonPositiveFocalAndSize) {
  expect_error(read_mutated("image_width: 1600", "image_width: -3"), "image_width");
  const auto p = good_.find("camera_matrix:");
  const auto d = good_.find("data: [", p);
  std::string text = good_;
  text.replace(d, 8, "data: [ -");
  expect_error(read_text(text), "focal");
}

TEST_F(MalformedFile, EmptyAndGarbage) {
  expect_error(read_text(""), "empty");
  expect_error(read_text("  \n\n"), "empty");
  const Status g = read_text(std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  EXPECT_EQ(g.code(), StatusCode::kInvalidArgument) << g.message();
  EXPECT_NE(g.message().find("bad.yml"), std::string::npos);
  const Status y = read_text("%YAML:1.0\n---\nfoo: [1, 2\n");
  EXPECT_EQ(y.code(), StatusCode::kInvalidArgument) << y.message();
  const Status z = read_text("%YAML:1.0\n---\nfoo: 1\n");
  expect_error(z, "camera_names");
}

// Inputs on which OpenCV 4.6's own YAML parser never returns (found by fuzz_rig_calibration, the
// reason the reader uses yaml-cpp): each must fail, promptly.
TEST_F(MalformedFile, InputsThatHangOpenCvsParser) {
  for (const std::string& text :
       {std::string("%YAML:1.\n   -l\n:\n\xff", 18), std::string("%YAML:1.\n -t-\n!\n!"),
        std::string("%YAML:1.0\n   -l\n:\nx")}) {
    const Status s = read_text(text);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.message();
  }
}

TEST_F(MalformedFile, ReservedCameraName) {
  expect_error(read_mutated("   - cam_1\n", "   - joint_rms_px\n"), "reserved");
  RigCalibration rig = make_rig();
  rig.cameras[1].name = "world_from_rig";
  EXPECT_EQ(write_rig_calibration(dir_ / "reserved.yml", rig).code(), StatusCode::kInvalidArgument);
}

TEST(CameraModelFile, MissingFileAndNothingHalfWritten) {
  ScratchDir dir;
  EXPECT_FALSE(read_rig_calibration(dir / "none.yml").ok());
  RigCalibration rig = make_rig();
  rig.cameras[1].R(0, 0) = 3.0;  // invalid: nothing may be written
  EXPECT_EQ(write_rig_calibration(dir / "out.yml", rig).code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(std::filesystem::exists(dir / "out.yml"));
  rig = make_rig();
  rig.cameras[2].name = "cam0";
  EXPECT_FALSE(write_rig_calibration(dir / "out.yml", rig).ok());
  rig.cameras[2].name = "2bad name";
  EXPECT_FALSE(write_rig_calibration(dir / "out.yml", rig).ok());
  EXPECT_FALSE(std::filesystem::exists(dir / "out.yml"));
}

}  // namespace
}  // namespace hc::calib
