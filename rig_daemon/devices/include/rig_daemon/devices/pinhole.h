// A calibrated pinhole camera with OpenCV's distortion model (k1, k2, p1, p2, k3), used by the
// simulated cameras to render marker dots where a calibrated real camera would see them.
//
//   x_c = R X + t;  (x, y) = (x_c / z_c, y_c / z_c);  r^2 = x^2 + y^2
//   x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
//   u = fx x' + cx;  v = fy y' + cy
// (OpenCV "Camera Calibration and 3D Reconstruction", calib3d; pixel centres at integer
// coordinates, (0, 0) the centre of the top-left pixel.) Camera frame: x right, y down, z forward.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/config.h"
#include "rig_daemon/devices/types.h"

namespace hc::devices::sim {

struct PinholeCamera {
  std::uint32_t width = 1600;
  std::uint32_t height = 1200;
  double fx = 2000.0, fy = 2000.0;     // px
  double cx = 799.5, cy = 599.5;       // px
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3
  Eigen::Matrix3d R_cam_world = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_cam_world = Eigen::Vector3d::Zero();  // m

  // Pixel of a world point, or nullopt when it is behind the camera (z_c <= 1 mm).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_world) const;
  // Depth z_c of a world point, m.
  double depth(const Eigen::Vector3d& p_world) const;
  // Camera centre in the world frame.
  Eigen::Vector3d center_world() const;
};

// R and t of a camera at `position` looking at `target` with image "up" towards world +z (or +y
// when looking straight down).
void look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target, PinholeCamera& cam);

// Reads a camera's calibration from a config map: width, height, fx, fy, cx, cy (default: image
// centre), distortion [k1, k2, p1, p2, k3], and either R (3x3 rows) + t [m] or position_m +
// look_at_m.
Status read_pinhole(ConfigNode node, PinholeCamera& cam);

}  // namespace hc::devices::sim

namespace hc::devices::sim {

class ProbeLayer;  // sim_scene.h

// How marker dots look in a rendered image (8-bit grey levels).
struct DotStyle {
  std::uint8_t background = 30;
  std::uint8_t dot = 220;
};

// Draws each world-frame dot centre as a disc of radius f * radius_m / depth pixels (the disc's
// foreshortening is ignored: dots are small) with anti-aliased edges (8 x 8 supersampling of edge
// pixels), so the intensity-weighted centroid of a dot lands on its projected centre to a few
// hundredths of a pixel. `frame` must be Mono8 of the camera's size; it is not cleared.
// Returns how many dots were drawn (in front of the camera and at least partly in the image).
// With an `occluder` (the probe, already composited into `frame`), a dot pixel the probe covers
// in front of the dot (probe depth < dot centre depth) shows the dot only through the uncovered
// fraction; a dot in front of the probe is drawn over it.
std::size_t render_dots(const PinholeCamera& cam, const std::vector<Eigen::Vector3d>& centers_m,
                        double radius_m, const DotStyle& style, Frame& frame,
                        const ProbeLayer* occluder = nullptr);

}  // namespace hc::devices::sim
