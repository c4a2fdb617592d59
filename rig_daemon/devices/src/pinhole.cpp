#include "rig_daemon/devices/pinhole.h"

#include "rig_daemon/devices/sim_scene.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace hc::devices::sim {

std::optional<Eigen::Vector2d> PinholeCamera::project(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d pc = R_cam_world * p_world + t_cam_world;
  if (!(pc.z() > 1e-3)) return std::nullopt;
  const double x = pc.x() / pc.z();
  const double y = pc.y() / pc.z();
  const double r2 = x * x + y * y;
  const auto& [k1, k2, p1, p2, k3] = distortion;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
  const double yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
  return Eigen::Vector2d(fx * xd + cx, fy * yd + cy);
}

double PinholeCamera::depth(const Eigen::Vector3d& p_world) const {
  return (R_cam_world * p_world + t_cam_world).z();
}

Eigen::Vector3d PinholeCamera::center_world() const {
  return -R_cam_world.transpose() * t_cam_world;
}

void look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target, PinholeCamera& cam) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d up(0.0, 0.0, 1.0);
  if (std::abs(z.dot(up)) > 0.999) up = Eigen::Vector3d(0.0, 1.0, 0.0);
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  cam.R_cam_world.row(0) = x.transpose();
  cam.R_cam_world.row(1) = y.transpose();
  cam.R_cam_world.row(2) = z.transpose();
  cam.t_cam_world = -cam.R_cam_world * position;
}

Status read_pinhole(ConfigNode node, PinholeCamera& cam) {
  node.optional("width", cam.width, Bounds::between(8, 16384));
  node.optional("height", cam.height, Bounds::between(8, 16384));
  cam.cx = 0.5 * (cam.width - 1.0);
  cam.cy = 0.5 * (cam.height - 1.0);
  node.optional("fx", cam.fx, Bounds::positive());
  node.optional("fy", cam.fy, Bounds::positive());
  node.optional("cx", cam.cx);
  node.optional("cy", cam.cy);
  node.optional("distortion", cam.distortion);
  std::array<std::array<double, 3>, 3> R{};
  std::array<double, 3> t{}, position{}, target{};
  const bool has_r = node.optional("R", R);
  const bool has_t = node.optional("t", t);
  const bool has_pos = node.optional("position_m", position);
  const bool has_target = node.optional("look_at_m", target);
  if (has_r != has_t) node.error("R and t must be given together");
  if (has_pos != has_target) node.error("position_m and look_at_m must be given together");
  if (has_r && has_pos) node.error("give either R and t or position_m and look_at_m, not both");
  if (!node.status().ok()) return node.status();
  if (has_r) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) cam.R_cam_world(i, j) = R[i][j];
    cam.t_cam_world = Eigen::Vector3d(t[0], t[1], t[2]);
    const double orth =
        (cam.R_cam_world * cam.R_cam_world.transpose() - Eigen::Matrix3d::Identity()).norm();
    if (orth > 1e-6 || cam.R_cam_world.determinant() < 0.0)
      node.error("R", "must be a rotation matrix (orthonormal, determinant +1)");
  } else if (has_pos) {
    const Eigen::Vector3d p(position[0], position[1], position[2]);
    const Eigen::Vector3d q(target[0], target[1], target[2]);
    if ((q - p).norm() < 1e-6)
      node.error("look_at_m", "must differ from position_m");
    else
      look_at(p, q, cam);
  }
  return node.status();
}

}  // namespace hc::devices::sim

namespace hc::devices::sim {

std::size_t render_dots(const PinholeCamera& cam, const std::vector<Eigen::Vector3d>& centers_m,
                        double radius_m, const DotStyle& style, Frame& frame,
                        const ProbeLayer* occluder) {
  constexpr int kSub = 8;                   // supersamples per axis on edge pixels
  constexpr double kHalfDiagonal = 0.7072;  // > sqrt(2) / 2: a pixel this far is fully in/out
  const int w = static_cast<int>(frame.width);
  const int h = static_cast<int>(frame.height);
  const double span = static_cast<double>(style.dot) - static_cast<double>(style.background);
  std::size_t drawn = 0;
  for (const Eigen::Vector3d& c : centers_m) {
    const std::optional<Eigen::Vector2d> uv = cam.project(c);
    if (!uv) continue;
    const double depth = cam.depth(c);
    const double r = cam.fx * radius_m / depth;
    // Clamped before the conversion: a dot projected far off the image would overflow an int.
    const auto clamp_px = [](double v, int lo, int hi) {
      return std::clamp(v, static_cast<double>(lo), static_cast<double>(hi));
    };
    const int x0 = static_cast<int>(std::floor(clamp_px(uv->x() - r - 1.0, 0, w)));
    const int x1 = static_cast<int>(std::ceil(clamp_px(uv->x() + r + 1.0, -1, w - 1)));
    const int y0 = static_cast<int>(std::floor(clamp_px(uv->y() - r - 1.0, 0, h)));
    const int y1 = static_cast<int>(std::ceil(clamp_px(uv->y() + r + 1.0, -1, h - 1)));
    if (x0 > x1 || y0 > y1) continue;
    ++drawn;
    for (int y = y0; y <= y1; ++y) {
      std::uint8_t* row = frame.pixels.data() + static_cast<std::size_t>(y) * frame.stride_bytes;
      for (int x = x0; x <= x1; ++x) {
        const double dx = x - uv->x();
        const double dy = y - uv->y();
        const double d = std::sqrt(dx * dx + dy * dy);
        double coverage = 0.0;
        if (d <= r - kHalfDiagonal) {
          coverage = 1.0;
        } else if (d < r + kHalfDiagonal) {
          int inside = 0;
          for (int sy = 0; sy < kSub; ++sy)
            for (int sx = 0; sx < kSub; ++sx) {
              const double ex = dx - 0.5 + (sx + 0.5) / kSub;
              const double ey = dy - 0.5 + (sy + 0.5) / kSub;
              inside += (ex * ex + ey * ey <= r * r) ? 1 : 0;
            }
          coverage = static_cast<double>(inside) / (kSub * kSub);
        }
        if (coverage <= 0.0) continue;
        double v = style.background + span * coverage;
        if (occluder != nullptr) {
          const ProbeLayer::Sample p = occluder->at(x, y);
          const double cover = static_cast<double>(p.body) + p.marker;
          if (cover > 0.0) {
            const double probe = p.body * static_cast<double>(occluder->body_grey()) +
                                 p.marker * static_cast<double>(occluder->marker_grey());
            if (p.depth < depth) {  // the probe in front: the dot shows where it is uncovered
              v = probe + (1.0 - cover) * v;
            } else {  // the dot in front of the probe
              const double under = probe + (1.0 - cover) * style.background;
              v = coverage * style.dot + (1.0 - coverage) * under;
            }
            row[x] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
            continue;
          }
        }
        const auto value = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
        // Overlapping dots keep the stronger contrast.
        if (span >= 0.0 ? value > row[x] : value < row[x]) row[x] = value;
      }
    }
  }
  return drawn;
}

}  // namespace hc::devices::sim
