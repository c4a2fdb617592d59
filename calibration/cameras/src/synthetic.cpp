#include "calibration/cameras/synthetic.h"

#include <cmath>
#include <random>

namespace hc::calib {

namespace {
constexpr double kPi = 3.14159265358979323846;
double rad(double deg) { return deg * kPi / 180.0; }
}  // namespace

std::vector<CameraModel> make_half_circle_rig(const SyntheticRigOptions& o) {
  // World: look-at point at the origin, y down; camera at angle a sits at r (sin a, 0, -cos a)
  // and looks at the origin.
  std::vector<CameraModel> out;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
  for (int i = 0; i < o.cameras; ++i) {
    const double a = o.cameras == 1 ? 0.0 : rad(-0.5 * o.arc_deg + o.arc_deg * i / (o.cameras - 1));
    const Eigen::Vector3d p = o.radius_m * Eigen::Vector3d(std::sin(a), 0.0, -std::cos(a));
    Eigen::Matrix3d R;
    R.row(0) = Eigen::Vector3d(std::cos(a), 0.0, std::sin(a));
    R.row(1) = Eigen::Vector3d(0.0, 1.0, 0.0);
    R.row(2) = Eigen::Vector3d(-std::sin(a), 0.0, std::cos(a));
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
  if (cos_angle < std::cos(rad(max_angle_deg))) return false;
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
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d look = rig_look_at(rig);
  const Eigen::Vector3d board_centre =
      0.5 * (board.corner(0) + board.corner(board.corner_count() - 1));
  std::vector<Eigen::Isometry3d> out;
  for (int attempt = 0; attempt < 100000 && static_cast<int>(out.size()) < count; ++attempt) {
    // Face a random point on the arc through the cameras (between two neighbouring cameras'
    // directions), then tilt and spin.
    const std::size_t k = rig.size() > 1 ? rng() % (rig.size() - 1) : 0;
    const double f = 0.5 * (u(rng) + 1.0);
    const Eigen::Vector3d d0 = (rig[k].center_m() - look).normalized();
    const Eigen::Vector3d d1 =
        (rig[std::min(k + 1, rig.size() - 1)].center_m() - look).normalized();
    const Eigen::Vector3d to_cam = ((1.0 - f) * d0 + f * d1).normalized();
    Eigen::Matrix3d R;
    R.col(2) = -to_cam;
    R.col(0) = Eigen::Vector3d(0, 1, 0).cross(R.col(2)).normalized();
    R.col(1) = R.col(2).cross(R.col(0));
    // Random draws in separate statements (argument evaluation order is unspecified).
    const double ax = u(rng), ay = u(rng), az = u(rng);
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(rad(tilt_deg) * ax, Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(rad(tilt_deg) * ay, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(rad(20.0) * az, Eigen::Vector3d::UnitZ()))
                                     .toRotationMatrix();
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = R * tilt;
    const double ox = u(rng), oy = u(rng), oz = u(rng);
    const Eigen::Vector3d c = look + offset_m * Eigen::Vector3d(ox, oy, oz);
    pose.translation() = c - pose.linear() * board_centre;
    int seen = 0;
    for (const CameraModel& cam : rig) seen += board_visible(cam, board, pose) ? 1 : 0;
    if (seen >= min_cameras) out.push_back(pose);
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

}  // namespace hc::calib
