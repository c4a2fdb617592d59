#include "rig_daemon/simulation/sim_dots.h"

#include "rig_daemon/simulation/sim_scene.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace hc::devices::sim {

CameraModel default_camera() {
  CameraModel cam;
  cam.width = 1600;
  cam.height = 1200;
  cam.fx = cam.fy = 2000.0;
  cam.cx = 799.5;
  cam.cy = 599.5;
  return cam;
}

}  // namespace hc::devices::sim

namespace hc::devices::sim {

std::size_t render_dots(const CameraModel& cam, const std::vector<Eigen::Vector3d>& centers_m,
                        double radius_m, const DotStyle& style, Frame& frame,
                        const ProbeLayer* occluder) {
  constexpr int kSub = 8;                   // supersamples per axis on edge pixels
  constexpr double kHalfDiagonal = 0.7072;  // > sqrt(2) / 2: a pixel this far is fully in/out
  const int w = static_cast<int>(frame.width);
  const int h = static_cast<int>(frame.height);
  const double span = static_cast<double>(style.dot) - static_cast<double>(style.background);
  std::size_t drawn = 0;
  for (const Eigen::Vector3d& c : centers_m) {
    // The renderer's near plane: 1 mm (a dot closer would cover the image).
    const double depth = cam.depth_m(c);
    if (!(depth > 1e-3)) continue;
    const std::optional<Eigen::Vector2d> uv = cam.project(c);
    if (!uv) continue;
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
