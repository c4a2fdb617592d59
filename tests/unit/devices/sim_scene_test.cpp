// The simulated scene: probe geometry and rendering with occlusion, the calibration board (checked
// with OpenCV's own chessboard detector), the seeded board pose sequence.
#include "rig_daemon/simulation/sim_scene.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <set>

#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "sim_support.h"

namespace hc::devices {
namespace {

using testing::SimRig;

sim::ProbeGeometry probe_at(double x, double y, double z) {
  return sim::ProbeGeometry::at(ArmPose{x, y, z, 0.0}, 0.005, sim::ProbeLook{});
}

Frame blank(const CameraModel& cam, std::uint8_t grey) {
  Frame f;
  f.format = PixelFormat::kMono8;
  f.width = cam.width;
  f.height = cam.height;
  f.stride_bytes = cam.width;
  f.pixels.assign(static_cast<std::size_t>(cam.width) * cam.height, grey);
  return f;
}

TEST(SimScene, ProbeRayHitsMatchTheGeometry) {
  // Tip at z = 0.05: sphere centre z = 0.055 (r = 5 mm), shaft r = 2 mm up to z = 0.205, marker
  // balls r = 2.5 mm at 60 and 110 mm from the tip (ProbeLook defaults).
  const sim::ProbeGeometry g = probe_at(0.0, 0.0, 0.05);
  int part = 0;
  // Straight down the axis: the shaft's top cap at z = 0.205.
  EXPECT_NEAR(g.ray_hit({0, 0, 0.5}, {0, 0, -1}, 0.0, &part), 0.295, 1e-12);
  EXPECT_EQ(part, sim::ProbeGeometry::kBody);
  // Sideways through the sphere's centre: its surface at x = 0.005.
  EXPECT_NEAR(g.ray_hit({0.1, 0, 0.055}, {-1, 0, 0}, 0.0, &part), 0.095, 1e-12);
  EXPECT_EQ(part, sim::ProbeGeometry::kBody);
  // Sideways through the shaft: x = 0.002; grown by 1 mm: x = 0.003.
  EXPECT_NEAR(g.ray_hit({0.1, 0, 0.09}, {-1, 0, 0}, 0.0, &part), 0.098, 1e-12);
  EXPECT_NEAR(g.ray_hit({0.1, 0, 0.09}, {-1, 0, 0}, 0.001), 0.097, 1e-12);
  // Through the first shaft marker (z = 0.11): the ball at x = 0.0025.
  EXPECT_NEAR(g.ray_hit({0.1, 0, 0.11}, {-1, 0, 0}, 0.0, &part), 0.0975, 1e-12);
  EXPECT_EQ(part, sim::ProbeGeometry::kMarker);
  EXPECT_NEAR(g.markers_m[1].z(), 0.16, 1e-15);
  // Misses: above the shaft, and beside it.
  EXPECT_TRUE(std::isinf(g.ray_hit({0.1, 0, 0.3}, {-1, 0, 0}, 0.0)));
  EXPECT_TRUE(std::isinf(g.ray_hit({0.1, 0.01, 0.09}, {-1, 0, 0}, 0.0)));
}

TEST(SimScene, UndistortInvertsTheDistortionModel) {
  CameraModel cam = sim::default_camera();
  cam.distortion = {-0.12, 0.05, 0.001, -0.0005, 0.01};
  for (double x = -0.35; x <= 0.35; x += 0.07)
    for (double y = -0.25; y <= 0.25; y += 0.05) {
      const std::optional<Eigen::Vector2d> uv = cam.project({x, y, 1.0});
      ASSERT_TRUE(uv);
      const Eigen::Vector2d n = cam.undistort_to_normalized(*uv);
      EXPECT_NEAR(n.x(), x, 1e-10);
      EXPECT_NEAR(n.y(), y, 1e-10);
    }
}

// A 1600 x 1200 camera 0.3 m from the probe, looking at the shaft from the side and above.
CameraModel hires_camera() {
  CameraModel cam = sim::default_camera();
  cam.fx = cam.fy = 3500.0;
  cam.distortion = {-0.05, 0.08, 0.0003, -0.0002, 0.0};
  look_at({0.25, -0.12, 0.22}, {0.0, 0.0, 0.12}, cam);
  return cam;
}

TEST(SimScene, ShaftMarkersRenderCentredOnTheirProjection) {
  const CameraModel cam = hires_camera();
  const sim::ProbeGeometry g = probe_at(0.0, 0.0, 0.05);
  sim::ProbeLayer layer;
  layer.render(cam, g, sim::ProbeLook{}, 1600, 1200);
  ASSERT_FALSE(layer.empty());
  for (const Eigen::Vector3d& m : g.markers_m) {
    const Eigen::Vector2d c = *cam.project(m);
    const double depth = cam.depth_m(m);
    const double r = cam.fx * 0.0025 / depth;
    double sum = 0.0, su = 0.0, sv = 0.0;
    for (int y = static_cast<int>(c.y() - r - 3); y <= static_cast<int>(c.y() + r + 3); ++y)
      for (int x = static_cast<int>(c.x() - r - 3); x <= static_cast<int>(c.x() + r + 3); ++x) {
        const double w = layer.at(x, y).marker;
        sum += w;
        su += w * x;
        sv += w * y;
      }
    // A ball's image is an ellipse whose centre lies off the projected centre by about
    // f (r / D)^2 tan(angle off the optical axis) = 3500 * (0.0025 / 0.3)^2 * 0.2 ~ 0.05 px; the
    // area is pi (f r / D)^2 to first order (the marker is a little larger than the shaft, which
    // does not hide it: the ball is in front of the shaft's silhouette).
    EXPECT_NEAR(su / sum, c.x(), 0.1);
    EXPECT_NEAR(sv / sum, c.y(), 0.1);
    EXPECT_NEAR(sum, std::numbers::pi * r * r, 0.02 * std::numbers::pi * r * r);
  }
  // The shaft's width in the image near the first marker ~ 2 f r_shaft / D.
  EXPECT_GT(layer.pixels(), 10000u);
}

TEST(SimScene, ProbeHidesExactlyTheMarkersTheTruthCallsOccluded) {
  // Two identical worlds, one with the probe hidden: a marker the truth calls visible must have
  // identical pixels in both frames; a marker behind the probe's body must show the probe's grey.
  sim::WorldOptions hidden;
  hidden.probe.visible = false;
  SimRig with(7), without(7, hidden);
  const std::string yaml =
      "{trigger: software, width: 800, height: 600, fx: 1600, fy: 1600,"
      " distortion: [-0.05, 0.02, 0, 0, 0], position_m: [0.2, -0.12, 0.27],"
      " look_at_m: [0, 0, 0.05]}";
  std::vector<sim::GroundTruth> truths;
  with.world->set_ground_truth_callback([&](const sim::GroundTruth& g) { truths.push_back(g); });
  std::vector<Frame> frames[2];
  SimRig* rigs[2] = {&with, &without};
  for (int k = 0; k < 2; ++k) {
    SimRig& rig = *rigs[k];
    auto arm = rig.make<Arm>("arm");
    auto cam = rig.make<Camera>("cam", yaml);
    ASSERT_TRUE(arm->activate().ok());
    ASSERT_TRUE(cam->activate().ok());
    ArmCommand home;
    home.type = ArmCommand::Type::kHome;
    ASSERT_TRUE(arm->write(home).ok());
    rig.clock->advance_ns(10'000'000'000);
    ArmCommand move;
    move.type = ArmCommand::Type::kMoveTo;
    move.target = {0.003, 0.002, 0.047, 0.0};  // 3 mm into the specimen (top at 0.05)
    move.sequence = 2;
    ASSERT_TRUE(arm->write(move).ok());
    rig.clock->advance_ns(10'000'000'000);
    ASSERT_TRUE(cam->software_trigger().ok());
    ASSERT_TRUE(cam->read(frames[k], std::chrono::milliseconds(200)).ok());
    ASSERT_EQ(frames[k].size(), 1u);
  }
  ASSERT_EQ(truths.size(), 1u);
  const sim::GroundTruth& g = truths[0];
  ASSERT_EQ(g.cameras.size(), 1u);
  EXPECT_EQ(g.cameras[0].camera, "cam");
  const std::set<std::uint32_t> occluded(g.cameras[0].occluded.begin(),
                                         g.cameras[0].occluded.end());
  EXPECT_GT(occluded.size(), 10u);   // the sphere and shaft hide a patch of the 3 mm grid
  EXPECT_LT(occluded.size(), 200u);  // but not most of the 441 markers
  EXPECT_TRUE(g.cameras[0].out_of_view.empty());
  EXPECT_TRUE(g.probe_shown);
  EXPECT_NEAR(g.probe_geometry.tip_m.z(), 0.047, 1e-12);
  const CameraModel cam = with.world->cameras().at(0).camera;
  const Frame& a = frames[0][0];
  const Frame& b = frames[1][0];
  std::size_t compared = 0, behind_body = 0;
  for (std::size_t i = 0; i < g.markers_m.size(); ++i) {
    const Eigen::Vector2d c = *cam.project(g.markers_m[i]);
    // The pixels the dot touches: within its radius plus half a pixel diagonal.
    const double r = cam.fx * 0.0006 / cam.depth_m(g.markers_m[i]) + 0.7072;
    if (!occluded.count(static_cast<std::uint32_t>(i))) {
      for (int y = static_cast<int>(c.y() - r); y <= static_cast<int>(c.y() + r) + 1; ++y)
        for (int x = static_cast<int>(c.x() - r); x <= static_cast<int>(c.x() + r) + 1; ++x) {
          if (std::hypot(x - c.x(), y - c.y()) > r) continue;
          const std::size_t at =
              static_cast<std::size_t>(y) * a.width + static_cast<std::size_t>(x);
          ASSERT_EQ(a.pixels[at], b.pixels[at]) << "marker " << i << " at " << x << "," << y;
          ++compared;
        }
      continue;
    }
    // Occluded: where the ray to the centre meets the (not grown) probe body, the centre pixel
    // is the probe's grey (90) unless the dot is in front of the probe.
    const Eigen::Vector3d o = cam.center_m();
    const Eigen::Vector3d d = (g.markers_m[i] - o).normalized();
    int part = 0;
    // The probe shrunk by 1.5 px: the whole centre pixel is inside its silhouette.
    const double s =
        g.probe_geometry.ray_hit(o, d, -1.5 * cam.depth_m(g.markers_m[i]) / cam.fx, &part);
    if (part == sim::ProbeGeometry::kBody && s < (g.markers_m[i] - o).norm() - 0.001) {
      const auto x = static_cast<std::size_t>(std::lround(c.x()));
      const auto y = static_cast<std::size_t>(std::lround(c.y()));
      EXPECT_NEAR(a.pixels[y * a.width + x], 90, 1) << "marker " << i;
      ++behind_body;
    }
  }
  EXPECT_GT(compared, 3000u);
  EXPECT_GT(behind_body, 5u);
}

TEST(SimScene, BoardCornersMatchOpenCvDetection) {
  // OpenCV 4.6 findChessboardCorners + cornerSubPix on the rendered board must find the true
  // projected inner corners: the supersampled edges put them within a few hundredths of a pixel.
  CameraModel cam;
  cam.width = 1024;
  cam.height = 768;
  cam.fx = cam.fy = 2400.0;
  cam.cx = 515.0;
  cam.cy = 380.0;
  cam.distortion = {-0.08, 0.1, 0.0005, -0.0003, 0.0};
  look_at({0.18, -0.1, 0.3}, {0.0, 0.0, 0.06}, cam);
  sim::BoardSpec spec;  // 9 x 6 inner corners of 6 mm
  sim::BoardMotion motion;
  motion.poses = 8;
  motion.seed = 5;
  const std::vector<sim::BoardPose> poses = sim::board_poses(spec, motion, {0.0, 0.0, 0.05});
  int checked = 0;
  double worst = 0.0, sum = 0.0;
  for (const sim::BoardPose& pose : poses) {
    if (!sim::board_visible(cam, spec, pose, 20.0, 60.0)) continue;
    Frame f = blank(cam, 30);
    ASSERT_GT(sim::render_board(cam, spec, pose, f), 1000u);
    cv::Mat img(static_cast<int>(f.height), static_cast<int>(f.width), CV_8UC1, f.pixels.data());
    std::vector<cv::Point2f> corners;
    ASSERT_TRUE(cv::findChessboardCorners(img, cv::Size(spec.cols, spec.rows), corners,
                                          cv::CALIB_CB_ADAPTIVE_THRESH));
    cv::cornerSubPix(img, corners, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
    for (const cv::Point2f& p : corners) {
      double best = 1e9;  // OpenCV may order the grid from either end
      for (int j = 0; j < spec.rows; ++j)
        for (int i = 0; i < spec.cols; ++i) {
          const Eigen::Vector2d t = *cam.project(pose.R * spec.corner(i, j) + pose.t);
          best = std::min(best, std::hypot(t.x() - p.x, t.y() - p.y));
        }
      worst = std::max(worst, best);
      sum += best;
    }
    ++checked;
  }
  ASSERT_GE(checked, 3);
  EXPECT_LT(sum / (checked * spec.cols * spec.rows), 0.05);
  EXPECT_LT(worst, 0.15);
}

TEST(SimScene, BoardSeenFromBehindIsNotDrawn) {
  CameraModel cam;
  cam.width = 320;
  cam.height = 240;
  cam.fx = cam.fy = 400.0;
  cam.cx = 159.5;
  cam.cy = 119.5;
  look_at({0.0, -0.05, 0.4}, {0.0, 0.0, 0.05}, cam);
  sim::BoardSpec spec;
  sim::BoardPose up =
      sim::board_poses(spec, sim::BoardMotion{1, 1, 0.0, 0.0, {0, 0}, {0, 0}}, {0.0, 0.0, 0.05})[0];
  EXPECT_TRUE(sim::board_visible(cam, spec, up));
  Frame f = blank(cam, 30);
  EXPECT_GT(sim::render_board(cam, spec, up, f), 100u);
  sim::BoardPose flipped = up;  // face down: the camera sees the back
  flipped.R.col(1) *= -1.0;
  flipped.R.col(2) *= -1.0;
  EXPECT_FALSE(sim::board_visible(cam, spec, flipped));
  Frame g = blank(cam, 30);
  EXPECT_EQ(sim::render_board(cam, spec, flipped, g), 0u);
}

TEST(SimScene, BoardPosesAreSeededTiltedAndSeenBySubsets) {
  sim::BoardSpec spec;
  sim::BoardMotion motion;
  motion.poses = 24;
  motion.seed = 3;
  const Eigen::Vector3d centre(0.0, 0.0, 0.05);
  const std::vector<sim::BoardPose> a = sim::board_poses(spec, motion, centre);
  const std::vector<sim::BoardPose> b = sim::board_poses(spec, motion, centre);
  ASSERT_EQ(a.size(), 24u);
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].R, b[k].R);  // same seed, same sequence
    EXPECT_NEAR((a[k].R.transpose() * a[k].R - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
    EXPECT_NEAR(a[k].R.determinant(), 1.0, 1e-12);
    const double tilt = std::acos(-a[k].R(2, 2)) * 180.0 / std::numbers::pi;
    EXPECT_LE(tilt, 35.0 + 1e-9);
    if (k % 4 == 3) {
      EXPECT_GE(tilt, 28.0 - 1e-9);
    }
    const Eigen::Vector3d g = a[k].R * spec.grid_center() + a[k].t - centre;
    EXPECT_LE(std::abs(g.x()), 0.012 + 1e-12);
    EXPECT_LE(std::abs(g.y()), 0.012 + 1e-12);
    EXPECT_GE(g.z(), -1e-12);
    EXPECT_LE(g.z(), 0.03 + 1e-12);
  }
  motion.seed = 4;
  EXPECT_NE(sim::board_poses(spec, motion, centre)[0].R, a[0].R);
  // The seven cameras of rig_daemon/examples/rig_sim.yaml (a half circle, 320 x 240, f = 400):
  // every pose is seen by some cameras, some only by a subset, every camera sees several.
  std::vector<CameraModel> cams(7);
  for (int i = 0; i < 7; ++i) {
    cams[static_cast<std::size_t>(i)].width = 320;
    cams[static_cast<std::size_t>(i)].height = 240;
    cams[static_cast<std::size_t>(i)].fx = cams[static_cast<std::size_t>(i)].fy = 400.0;
    cams[static_cast<std::size_t>(i)].cx = 159.5;
    cams[static_cast<std::size_t>(i)].cy = 119.5;
    const double phi = -std::numbers::pi * i / 6.0;
    look_at({0.3 * std::cos(phi), 0.3 * std::sin(phi), 0.3}, {0, 0, 0.05},
            cams[static_cast<std::size_t>(i)]);
  }
  int subset_poses = 0;
  std::vector<int> seen_by_camera(7, 0);
  for (const sim::BoardPose& p : a) {
    int seen = 0;
    for (int i = 0; i < 7; ++i)
      if (sim::board_visible(cams[static_cast<std::size_t>(i)], spec, p)) {
        ++seen;
        ++seen_by_camera[static_cast<std::size_t>(i)];
      }
    EXPECT_GE(seen, 1);
    if (seen < 7) ++subset_poses;
  }
  EXPECT_GE(subset_poses, 3);
  for (int n : seen_by_camera) EXPECT_GE(n, 6);
}

}  // namespace
}  // namespace hc::devices
