// What the simulated cameras see besides the specimen's marker dots: the contact probe (tip sphere,
// shaft and two shaft markers, thesis 4.4: "two markers on the white shaft") and a calibration
// chessboard. Geometry, ray casting and anti-aliased rendering through a CameraModel.
//
// Probe (world frame, m): the tip sphere of radius `radius_m` (world probe_radius_m) whose lowest
// point is the arm's tool tip; a cylindrical shaft of radius shaft_radius_m from the sphere's
// centre `shaft_length_m` up along the probe axis (world +z: the 4-DOF arm holds the probe
// vertical), closed by a flat disc; two shaft markers, balls of radius marker_radius_m centred on
// the axis at marker_distances_m from the tip. Rendered flat (no lighting, so centroids are not
// biased): sphere and shaft in grey level `grey` (90 by default: darker than the specimen dots
// (220) and brighter than the background (30)), the shaft markers in `marker_grey` (255) — they
// are also about 4x the dots' radius, so a blob detector tells them apart by area and level. The
// shaft markers show in front of the shaft that passes through them (a real ball threaded on the
// shaft would lose a sliver of its image to the shaft above it and bias its centroid by pixels):
// each one's image is a whole ellipse whose area centroid is the projection of its centre to
// about f (r / D)^2 tan(off-axis angle), ~0.05 px at 0.3 m with f = 3500 px.
//
// Calibration board: a chessboard of cols x rows inner corners (OpenCV's pattern size) of
// square_m squares, a white margin of margin_squares squares around the (cols+1) x (rows+1)
// squares. Board frame (OpenCV's object points): inner corner (i, j) at (i square_m, j square_m,
// 0), i = 0..cols-1 along x, j = 0..rows-1 along y; the printed face is seen from the board's -z
// side, i.e. a camera looking at the face looks along +z_board (as with solvePnP). World from
// board: x_world = R x_board + t. Square (a, b), a = floor(x / square_m) in [-1, cols - 1],
// b = floor(y / square_m) in [-1, rows - 1], is black when a + b is even (so the square between
// inner corners (0, 0) and (1, 1) is black).
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/devices/types.h"
#include "rig_daemon/simulation/sim_dots.h"

namespace hc::devices::sim {

// How the probe looks. Keys (world: probe: {...}): visible, shaft_radius_m, shaft_length_m,
// marker_distances_m [d1, d2], marker_radius_m, grey, marker_grey.
struct ProbeLook {
  bool visible = true;
  double shaft_radius_m = 0.002;                         // a 4 mm shaft
  double shaft_length_m = 0.15;                          // from the tip sphere's centre
  std::array<double, 2> marker_distances_m{0.06, 0.11};  // from the tip (lowest point), along axis
  double marker_radius_m = 0.0025;                       // balls, wider than the shaft
  std::uint8_t grey = 90;
  std::uint8_t marker_grey = 255;
  Status read(ConfigNode node);
  Status validate() const;
};

// The probe's geometry at one instant.
struct ProbeGeometry {
  Eigen::Vector3d tip_m = Eigen::Vector3d::Zero();  // lowest point of the sphere
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit, from the tip up the shaft
  double radius_m = 0.005;
  double shaft_radius_m = 0.002;
  double shaft_length_m = 0.15;
  std::array<Eigen::Vector3d, 2> markers_m{};  // shaft marker centres
  double marker_radius_m = 0.0025;

  static ProbeGeometry at(const ArmPose& pose, double radius_m, const ProbeLook& look);
  Eigen::Vector3d sphere_center_m() const { return tip_m + axis * radius_m; }

  enum Part : int { kNone = 0, kBody = 1, kMarker = 2 };
  // Nearest hit s > 0 of the ray o + s d (d unit) with the probe grown by `inflate_m` in every
  // part, or +inf; `part` receives what was hit.
  double ray_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double inflate_m,
                 int* part = nullptr) const;
};

// Chessboard description. Keys: cols, rows (inner corners), square_m, margin_squares, black,
// white.
struct BoardSpec {
  int cols = 9;
  int rows = 6;
  double square_m = 0.006;
  double margin_squares = 1.0;  // white border around the squares (OpenCV needs a quiet zone)
  std::uint8_t black = 25;
  std::uint8_t white = 235;
  Status read(ConfigNode node);
  Status validate() const;
  // Inner corner (i, j) in the board frame.
  Eigen::Vector3d corner(int i, int j) const { return {i * square_m, j * square_m, 0.0}; }
  // Centre of the inner-corner grid in the board frame.
  Eigen::Vector3d grid_center() const {
    return {0.5 * (cols - 1) * square_m, 0.5 * (rows - 1) * square_m, 0.0};
  }
};

struct BoardPose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // x_world = R x_board + t
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

// How a calibration capture moves the board. Keys: poses, seed, max_tilt_deg, max_yaw_deg,
// offset_m [dx, dy] (uniform within +-), height_m [lo, hi] (above the specimen's top).
struct BoardMotion {
  int poses = 20;
  std::uint64_t seed = 1;
  double max_tilt_deg = 35.0;  // tilt of the face's normal away from world +z
  double max_yaw_deg = 20.0;   // rotation about the normal (kept small: no 180 deg ambiguity)
  std::array<double, 2> offset_m{0.012, 0.012};
  std::array<double, 2> height_m{0.0, 0.03};
};

// A seeded sequence of board poses around `center_m` (the specimen's top centre): the grid centre
// at center + (uniform offset, uniform height), the face's normal tilted by a uniform angle in
// [0, max_tilt] towards a uniform azimuth, then yawed; every 4th pose is tilted by at least 0.8
// max_tilt so that some poses face only the cameras on one side (the visibility graph matters).
std::vector<BoardPose> board_poses(const BoardSpec& spec, const BoardMotion& motion,
                                   const Eigen::Vector3d& center_m);

// Whether a camera sees the whole board: every inner corner projects into the image with
// `margin_px` to spare, in front of the camera, and the face is towards the camera at an angle
// below max_angle_deg from its normal.
bool board_visible(const CameraModel& cam, const BoardSpec& spec, const BoardPose& pose,
                   double margin_px = 2.0, double max_angle_deg = 75.0);

// Renders the board (only its front face; nothing when seen from behind) into a Mono8 frame with
// edge pixels supersampled 8 x 8; pixels off the board are left as they are. Returns the number
// of pixels touched.
std::size_t render_board(const CameraModel& cam, const BoardSpec& spec, const BoardPose& pose,
                         Frame& frame);

// The probe as one camera sees it: per-pixel coverage of body and markers and the depth of the
// nearest hit, over row spans that bound the probe's projection (only those pixels are cast).
class ProbeLayer {
 public:
  void render(const CameraModel& cam, const ProbeGeometry& probe, const ProbeLook& look, int width,
              int height);
  bool empty() const { return rows_.empty(); }
  // Coverage (body + marker, each in [0, 1]) and camera depth at a pixel (0, 0, +inf off-probe).
  struct Sample {
    float body = 0.0f, marker = 0.0f;
    float depth = std::numeric_limits<float>::infinity();
  };
  Sample at(int x, int y) const;
  // Composites the probe over the frame (pixels the probe covers).
  void composite(Frame& frame) const;
  std::size_t pixels() const { return samples_.size(); }
  std::uint8_t body_grey() const { return grey_; }
  std::uint8_t marker_grey() const { return marker_grey_; }

 private:
  struct Row {
    int y = 0, x0 = 0, x1 = -1;  // inclusive span
    std::size_t offset = 0;      // into samples_
  };
  std::vector<Row> rows_;  // sorted by y, at most one per row
  int first_row_ = 0;
  std::vector<int> row_index_;  // y - first_row_ -> index into rows_ or -1
  std::vector<Sample> samples_;
  std::uint8_t grey_ = 90, marker_grey_ = 255;
};

}  // namespace hc::devices::sim
