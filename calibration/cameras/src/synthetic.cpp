#include "calibration/cameras/synthetic.h"
#include "common/units.h"

#include <Eigen/Geometry>
#include <numbers>

#include <algorithm>
#include <cmath>
#include <random>

namespace hc::calib {

std::vector<CameraModel> make_half_circle_rig(const SyntheticRigOptions& o) {
  // World: look-at point at the origin, y down; camera at azimuth a and elevation e sits at
  // r (cos e sin a, -sin e, -cos e cos a) and looks at the origin.
  std::vector<CameraModel> out;
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t0 = Eigen::Vector3d::Zero();
  for (int i = 0; i < o.cameras; ++i) {
    const double a = o.cameras == 1
                         ? 0.0
                         : units::deg_to_rad(-0.5 * o.arc_deg + o.arc_deg * i / (o.cameras - 1));
    const double e = units::deg_to_rad(o.elevation_deg);
    const Eigen::Vector3d p = o.radius_m * Eigen::Vector3d(std::cos(e) * std::sin(a), -std::sin(e),
                                                           -std::cos(e) * std::cos(a));
    Eigen::Matrix3d R;
    R.row(2) = -p.normalized();                                 // looks at the origin
    R.row(0) = Eigen::Vector3d(std::cos(a), 0.0, std::sin(a));  // horizontal, perpendicular to p
    R.row(1) = R.row(2).cross(R.row(0));
    const Eigen::Vector3d t = -R * p;
    if (i == 0) {
      R0 = R;
      t0 = t;
    }
    CameraModel c;
    c.name = "cam" + std::to_string(i);
    c.width = o.width;
    c.height = o.height;
    c.fx = o.focal_px * (1.0 + 0.01 * i);
    c.fy = c.fx * 1.002;
    c.cx = 0.5 * o.width + 7.0 - 3.0 * i;
    c.cy = 0.5 * o.height - 5.0 + 2.0 * i;
    c.distortion = o.distortion;
    // Relative to camera 0: x_cam = R x_world + t, x_world = R0^T (x_rig - t0).
    c.R = R * R0.transpose();
    c.t_m = t - c.R * t0;
    out.push_back(c);
  }
  return out;
}

Eigen::Vector3d rig_look_at(const std::vector<CameraModel>& rig) {
  // Camera 0 looks along its +z at the look-at point, at the distance of its neighbours' centres
  // from it when available; make_half_circle_rig puts it at radius along +z.
  const double r = rig.size() > 1
                       ? [&] {
                           // Every camera is at the same distance r from the look-at point L =
                           // (0, 0, r): |c1 - L| = r gives r = |c1|^2 / (2 c1.z).
                           const Eigen::Vector3d c1 = rig[1].center_m();
                           return c1.squaredNorm() / (2.0 * c1.z());
                         }()
                       : 1.0;
  return {0.0, 0.0, r};
}

bool board_visible(const CameraModel& camera, const BoardSpec& board,
                   const Eigen::Isometry3d& rig_from_board, double max_angle_deg,
                   double margin_px) {
  const Eigen::Matrix3d Rcb = camera.R * rig_from_board.linear();
  const Eigen::Vector3d tcb = camera.R * rig_from_board.translation() + camera.t_m;
  // The front: the board's +z axis points away from the camera (as OpenCV's board poses).
  const Eigen::Vector3d centre =
      Rcb * (0.5 * (board.corner(0) + board.corner(board.corner_count() - 1))) + tcb;
  const double cos_angle = Rcb.col(2).dot(centre.normalized());
  if (cos_angle < std::cos(units::deg_to_rad(max_angle_deg))) return false;
  for (int id = 0; id < board.corner_count(); ++id) {
    const auto p = camera.project(rig_from_board * board.corner(id));
    if (!p || p->x() < margin_px || p->y() < margin_px || p->x() > camera.width - margin_px ||
        p->y() > camera.height - margin_px)
      return false;
  }
  // The white margin and outer squares too (the detector needs the quiet zone).
  const double s = board.square_m;
  for (const Eigen::Vector3d& q :
       {Eigen::Vector3d(-2 * s, -2 * s, 0), Eigen::Vector3d((board.cols + 1) * s, -2 * s, 0),
        Eigen::Vector3d(-2 * s, (board.rows + 1) * s, 0),
        Eigen::Vector3d((board.cols + 1) * s, (board.rows + 1) * s, 0)}) {
    const auto p = camera.project(rig_from_board * q);
    if (!p || p->x() < 0 || p->y() < 0 || p->x() > camera.width - 1 || p->y() > camera.height - 1)
      return false;
  }
  return true;
}

std::vector<Eigen::Isometry3d> random_board_poses(const std::vector<CameraModel>& rig,
                                                  const BoardSpec& board, int count,
                                                  std::uint32_t seed, int min_cameras,
                                                  double offset_m, double tilt_deg) {
  BoardPoseOptions o;
  o.count = count;
  o.seed = seed;
  o.min_cameras = min_cameras;
  o.offset_m = Eigen::Vector3d::Constant(offset_m);
  o.min_tilt_deg = 0.0;
  o.max_tilt_deg = tilt_deg;
  o.per_axis_tilt = true;
  return random_board_poses(rig, board, o);
}

std::vector<Eigen::Isometry3d> random_board_poses(const std::vector<CameraModel>& rig,
                                                  const BoardSpec& board,
                                                  const BoardPoseOptions& o) {
  if (rig.empty()) return {};
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d look = rig_look_at(rig);
  const Eigen::Vector3d board_centre =
      0.5 * (board.corner(0) + board.corner(board.corner_count() - 1));
  // The world's down direction in the rig (camera 0's) frame: camera 0's y axis on a level rig;
  // on an elevated one (balanced mode) the normal of the plane through the camera centres.
  Eigen::Vector3d down(0.0, 1.0, 0.0);
  if (!o.per_axis_tilt && rig.size() >= 3) {
    const Eigen::Vector3d n = (rig.back().center_m() - rig.front().center_m())
                                  .cross(rig[rig.size() / 2].center_m() - rig.front().center_m());
    if (n.norm() > 1e-9) down = n.normalized() * (n.y() >= 0.0 ? 1.0 : -1.0);
  }
  std::vector<Eigen::Isometry3d> out;
  for (int attempt = 0; attempt < 200000 && static_cast<int>(out.size()) < o.count; ++attempt) {
    // Face a random point on the arc through the cameras (between two neighbouring cameras'
    // directions), then tilt and spin.
    Eigen::Vector3d to_cam;
    if (o.per_axis_tilt) {
      const std::size_t k = rig.size() > 1 ? rng() % (rig.size() - 1) : 0;
      const double f = 0.5 * (u(rng) + 1.0);
      const Eigen::Vector3d d0 = (rig[k].center_m() - look).normalized();
      const Eigen::Vector3d d1 =
          (rig[std::min(k + 1, rig.size() - 1)].center_m() - look).normalized();
      to_cam = ((1.0 - f) * d0 + f * d1).normalized();
    } else {
      // Balanced: a camera drawn uniformly (the ends of the arc as often as the middle), the board
      // facing it or up to halfway towards a neighbour.
      const std::size_t j = rng() % rig.size();
      const double f = u(rng);
      const std::size_t n = f < 0.0 ? (j > 0 ? j - 1 : j) : std::min(j + 1, rig.size() - 1);
      const Eigen::Vector3d d0 = (rig[j].center_m() - look).normalized();
      const Eigen::Vector3d d1 = (rig[n].center_m() - look).normalized();
      to_cam = ((1.0 - 0.5 * std::abs(f)) * d0 + 0.5 * std::abs(f) * d1).normalized();
    }
    Eigen::Matrix3d R;
    R.col(2) = -to_cam;
    R.col(0) = down.cross(R.col(2)).normalized();
    R.col(1) = R.col(2).cross(R.col(0));
    // Random draws in separate statements (argument evaluation order is unspecified).
    const double ax = u(rng), ay = u(rng), az = u(rng);
    Eigen::Matrix3d tilt;
    if (o.per_axis_tilt) {
      tilt = (Eigen::AngleAxisd(units::deg_to_rad(o.max_tilt_deg) * ax, Eigen::Vector3d::UnitX()) *
              Eigen::AngleAxisd(units::deg_to_rad(o.max_tilt_deg) * ay, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(units::deg_to_rad(o.spin_deg) * az, Eigen::Vector3d::UnitZ()))
                 .toRotationMatrix();
    } else {
      // Tilt of a magnitude in [min, max] about a random axis in the board plane.
      const double azimuth = std::numbers::pi * ax;
      const double angle =
          units::deg_to_rad(o.min_tilt_deg + 0.5 * (ay + 1.0) * (o.max_tilt_deg - o.min_tilt_deg));
      tilt = (Eigen::AngleAxisd(angle, Eigen::Vector3d(std::cos(azimuth), std::sin(azimuth), 0.0)) *
              Eigen::AngleAxisd(units::deg_to_rad(o.spin_deg) * az, Eigen::Vector3d::UnitZ()))
                 .toRotationMatrix();
    }
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = R * tilt;
    const double ox = u(rng), oy = u(rng), oz = u(rng);
    const Eigen::Vector3d c = look + o.offset_m.cwiseProduct(Eigen::Vector3d(ox, oy, oz));
    pose.translation() = c - pose.linear() * board_centre;
    int seen = 0, first = -1, last = -1;
    for (std::size_t i = 0; i < rig.size(); ++i)
      if (board_visible(rig[i], board, pose, o.max_view_angle_deg)) {
        ++seen;
        if (first < 0) first = static_cast<int>(i);
        last = static_cast<int>(i);
      }
    if (o.max_camera_span > 0 && last - first + 1 > o.max_camera_span) continue;
    if (seen >= o.min_cameras) out.push_back(pose);
  }
  return out;
}

std::vector<CameraObservations> synthetic_observations(const std::vector<CameraModel>& rig,
                                                       const BoardSpec& board,
                                                       const std::vector<Eigen::Isometry3d>& poses,
                                                       double noise_px, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_px);
  std::vector<CameraObservations> out;
  for (const CameraModel& c : rig) {
    CameraObservations obs;
    obs.name = c.name;
    obs.width = c.width;
    obs.height = c.height;
    for (std::size_t v = 0; v < poses.size(); ++v) {
      if (!board_visible(c, board, poses[v])) continue;
      ViewObservation view;
      view.view = static_cast<int>(v);
      for (int id = 0; id < board.corner_count(); ++id) {
        const Eigen::Vector2d p = *c.project(poses[v] * board.corner(id));
        view.ids.push_back(id);
        Eigen::Vector2d q = p;
        if (noise_px > 0) {
          // Two statements: the order of evaluation of function arguments is unspecified, and
          // g++ and clang draw them in opposite orders (different data from the same seed).
          q.x() += n(rng);
          q.y() += n(rng);
        }
        view.pixels.push_back(q);
      }
      obs.views.push_back(std::move(view));
    }
    out.push_back(std::move(obs));
  }
  return out;
}

SyntheticRigOptions capture_rig_options(int cameras) {
  SyntheticRigOptions o;
  o.cameras = cameras;
  // rig_sim_hires.yaml: centres 0.22 m from the axis and 0.195 m above the look-at point.
  o.radius_m = std::hypot(0.22, 0.195);
  o.elevation_deg = units::rad_to_deg(std::atan2(0.195, 0.22));
  o.arc_deg = 180.0;
  o.focal_px = 3500.0;
  o.distortion = {-0.045, 0.08, 0.0003, -0.0002, 0.0};  // rig_sim_hires.yaml's cam0
  return o;
}

CentreErrors compare_centres(const std::vector<CameraModel>& truth,
                             const std::vector<CameraModel>& got) {
  CentreErrors e;
  const std::size_t n = std::min(truth.size(), got.size());
  if (n == 0) return e;
  Eigen::Matrix3Xd A(3, n), B(3, n);
  for (std::size_t c = 0; c < n; ++c) {
    A.col(static_cast<Eigen::Index>(c)) = got[c].center_m();
    B.col(static_cast<Eigen::Index>(c)) = truth[c].center_m();
    e.raw_m = std::max(e.raw_m, (got[c].center_m() - truth[c].center_m()).norm());
  }
  // Eigen's Umeyama (least-squares similarity; with_scaling = false gives the rigid motion).
  const Eigen::Matrix4d T = n >= 3 ? Eigen::Matrix4d(Eigen::umeyama(A, B, false))
                                   : Eigen::Matrix4d(Eigen::Matrix4d::Identity());
  for (std::size_t c = 0; c < n; ++c) {
    const Eigen::Vector3d d = T.topLeftCorner<3, 3>() * A.col(static_cast<Eigen::Index>(c)) +
                              T.topRightCorner<3, 1>() - B.col(static_cast<Eigen::Index>(c));
    const Eigen::Vector3d axis = truth[c].R.row(2).transpose();
    e.aligned_per_camera_m.push_back(d.norm());
    e.aligned_m = std::max(e.aligned_m, d.norm());
    e.aligned_axial_m = std::max(e.aligned_axial_m, std::abs(d.dot(axis)));
    e.aligned_lateral_m = std::max(e.aligned_lateral_m, (d - d.dot(axis) * axis).norm());
  }
  return e;
}

BoardSpec capture_board() { return *parse_board_spec("chessboard:15x10:0.005"); }

BoardPoseOptions capture_board_poses(int count, std::uint32_t seed) {
  BoardPoseOptions o;
  o.count = count;
  o.seed = seed;
  o.min_cameras = 2;
  o.offset_m = Eigen::Vector3d::Constant(0.02);
  o.per_axis_tilt = false;
  o.min_tilt_deg = 20.0;
  o.max_tilt_deg = 50.0;
  return o;
}

}  // namespace hc::calib
