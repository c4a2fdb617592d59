// Projection and rendering of the simulated cameras.
#include <gtest/gtest.h>

#include <Eigen/LU>

#include <cmath>
#include <numbers>

#include "rig_daemon/devices/device.h"
#include "rig_daemon/simulation/sim_dots.h"

namespace hc::devices::sim {
namespace {

CameraModel simple_camera() {
  CameraModel cam;
  cam.width = 1600;
  cam.height = 1200;
  cam.fx = 1000.0;
  cam.fy = 1000.0;
  cam.cx = 800.0;
  cam.cy = 600.0;
  return cam;
}

TEST(Pinhole, KnownPointLandsOnTheExpectedPixel) {
  CameraModel cam = simple_camera();
  // Identity pose: u = fx X/Z + cx = 1000 * 0.1 + 800 = 900; v = 1000 * -0.05 + 600 = 550.
  auto uv = cam.project({0.1, -0.05, 1.0});
  ASSERT_TRUE(uv);
  EXPECT_NEAR(uv->x(), 900.0, 1e-9);
  EXPECT_NEAR(uv->y(), 550.0, 1e-9);
  // Radial distortion k1 = 0.1: r^2 = 0.0125, factor 1.00125 -> (900.125, 549.9375).
  cam.distortion = {0.1, 0.0, 0.0, 0.0, 0.0};
  uv = cam.project({0.1, -0.05, 1.0});
  EXPECT_NEAR(uv->x(), 900.125, 1e-9);
  EXPECT_NEAR(uv->y(), 549.9375, 1e-9);
  // Tangential p1 = 0.01: x' = x + 2 p1 x y = 0.1 - 0.0001; y' = y + p1 (r^2 + 2 y^2) = -0.05 +
  // 0.01 * (0.0125 + 0.005) = -0.049825 -> (899.9, 550.175).
  cam.distortion = {0.0, 0.0, 0.01, 0.0, 0.0};
  uv = cam.project({0.1, -0.05, 1.0});
  EXPECT_NEAR(uv->x(), 899.9, 1e-9);
  EXPECT_NEAR(uv->y(), 550.175, 1e-9);
  // Behind the camera: nothing.
  EXPECT_FALSE(cam.project({0.0, 0.0, -1.0}));
}

TEST(Pinhole, PoseMovesThePoint) {
  CameraModel cam = simple_camera();
  // Camera 0.5 m behind the origin along its own z: t = (0, 0, 0.5) -> point (0.1, 0, 0.5) sees
  // depth 1.0 and lands at u = 900.
  cam.t_m = {0.0, 0.0, 0.5};
  auto uv = cam.project({0.1, 0.0, 0.5});
  ASSERT_TRUE(uv);
  EXPECT_NEAR(uv->x(), 900.0, 1e-9);
  EXPECT_NEAR(cam.center_m().z(), -0.5, 1e-12);
}

TEST(Pinhole, LookAtPutsTheTargetOnThePrincipalPointWithZUp) {
  CameraModel cam = simple_camera();
  look_at({0.3, -0.2, 0.4}, {0.0, 0.0, 0.05}, cam);
  EXPECT_NEAR((cam.R * cam.R.transpose() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(cam.R.determinant(), 1.0, 1e-12);
  auto uv = cam.project({0.0, 0.0, 0.05});
  ASSERT_TRUE(uv);
  EXPECT_NEAR(uv->x(), 800.0, 1e-9);
  EXPECT_NEAR(uv->y(), 600.0, 1e-9);
  // A point above the target appears higher in the image (smaller v).
  EXPECT_LT(cam.project({0.0, 0.0, 0.08})->y(), 600.0);
  EXPECT_NEAR((cam.center_m() - Eigen::Vector3d(0.3, -0.2, 0.4)).norm(), 0.0, 1e-12);
}

Frame blank(const CameraModel& cam, std::uint8_t level) {
  Frame f;
  f.width = cam.width;
  f.height = cam.height;
  f.stride_bytes = cam.width;
  f.pixels.assign(static_cast<std::size_t>(cam.width) * cam.height, level);
  return f;
}

TEST(Pinhole, RenderedDotsHaveSubPixelCentroids) {
  CameraModel cam = simple_camera();
  cam.width = 200;
  cam.height = 160;
  cam.cx = 100.0;
  cam.cy = 80.0;
  const DotStyle style{30, 220};
  for (double radius_px : {2.5, 4.0, 7.3}) {
    for (double ox : {0.0, 0.13, 0.5, 0.77}) {
      const Eigen::Vector3d p(ox / 1000.0, -0.31 / 1000.0, 1.0);  // 1 m away: 1 mm = 1 px
      Frame f = blank(cam, style.background);
      ASSERT_EQ(render_dots(cam, {p}, radius_px / 1000.0, style, f), 1u);
      double sw = 0.0, sx = 0.0, sy = 0.0;
      for (std::uint32_t y = 0; y < f.height; ++y)
        for (std::uint32_t x = 0; x < f.width; ++x) {
          const double w = f.pixels[y * f.stride_bytes + x] - style.background;
          sw += w;
          sx += w * x;
          sy += w * y;
        }
      const Eigen::Vector2d expected = *cam.project(p);
      EXPECT_NEAR(sx / sw, expected.x(), 0.02) << radius_px << " " << ox;
      EXPECT_NEAR(sy / sw, expected.y(), 0.02) << radius_px << " " << ox;
      // Total intensity = disc area (pi r^2) x contrast, to rounding of the 8-bit levels.
      EXPECT_NEAR(sw / (style.dot - style.background), std::numbers::pi * radius_px * radius_px,
                  0.03 * std::numbers::pi * radius_px * radius_px + 1.0);
    }
  }
}

TEST(Pinhole, ReadsCalibrationFromConfig) {
  Result<Config> config = parse_config(
      "{width: 640, height: 480, fx: 500, fy: 510, distortion: [0.1, 0, 0, 0, 0],"
      " R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], t: [0, 0, 1]}",
      "cam.yaml");
  ASSERT_TRUE(config.ok());
  CameraModel cam;
  Status s = read_config(*config, [&](ConfigNode node) { return read_camera(node, cam); });
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(cam.width, 640);
  EXPECT_NEAR(cam.cx, 319.5, 1e-12);  // default: the image centre
  EXPECT_NEAR(cam.fy, 510.0, 1e-12);
  EXPECT_NEAR(cam.project({0, 0, 0})->x(), 319.5, 1e-12);

  Result<Config> bad =
      parse_config("{R: [[1, 0, 0], [0, 2, 0], [0, 0, 1]], t: [0, 0, 1]}", "b.yaml");
  ASSERT_TRUE(bad.ok());
  s = read_config(*bad, [&](ConfigNode node) { return read_camera(node, cam); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("rotation"), std::string::npos) << s.message();

  Result<Config> half = parse_config("{position_m: [0, 0, 1]}", "h.yaml");
  s = read_config(*half, [&](ConfigNode node) { return read_camera(node, cam); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::devices::sim
