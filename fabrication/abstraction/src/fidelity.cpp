#include "fabrication/abstraction/fidelity.h"

#include <fmt/format.h>

#include <random>

#include "fabrication/abstraction/sampling.h"
#include "geometry/mesh_distance.h"
#include "geometry/regular_triangulation.h"
#include "geometry/triangulation_2d.h"

namespace hc::abstraction {
namespace {

// For each point, whether it lies within `margin` of one of the balls.
template <int D, class Query>
Result<std::vector<std::uint8_t>> near_balls(const Balls<D>& balls, double margin,
                                             const std::vector<Eigen::Matrix<double, D, 1>>& pts,
                                             Query query) {
  std::vector<std::uint8_t> out(pts.size(), 0);
  if (balls.size() < static_cast<std::size_t>(D + 1)) {
    for (std::size_t i = 0; i < pts.size(); ++i) {
      for (std::size_t b = 0; b < balls.size(); ++b) {
        if ((pts[i] - balls.centres[b]).norm() < balls.radii[b] + margin) out[i] = 1;
      }
    }
    return out;
  }
  std::vector<double> w(balls.size());
  for (std::size_t b = 0; b < w.size(); ++b) w[b] = std::pow(balls.radii[b] + margin, 2);
  HC_ASSIGN_OR_RETURN(auto q, query(balls.centres, w, pts));
  for (std::size_t i = 0; i < pts.size(); ++i) out[i] = q.power[i] < 0;
  return out;
}

std::vector<Eigen::Vector2d> outline_points(const Polygon2& p, std::size_t count,
                                            std::mt19937_64& rng) {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> seg;
  std::vector<double> len;
  for (const auto& l : p.loops)
    for (std::size_t i = 0; i < l.size(); ++i) {
      seg.emplace_back(l[i], l[(i + 1) % l.size()]);
      len.push_back((seg.back().second - seg.back().first).norm());
    }
  std::vector<Eigen::Vector2d> out;
  auto table = AliasTable::build(len);
  if (!table.ok()) return out;
  std::uniform_real_distribution<double> u(0, 1);
  for (std::size_t i = 0; i < count; ++i) {
    const auto& s = seg[table->draw(rng)];
    out.push_back(s.first + u(rng) * (s.second - s.first));
  }
  return out;
}

double distance_to_outline(const Polygon2& p, const Eigen::Vector2d& q) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& l : p.loops)
    for (std::size_t i = 0; i < l.size(); ++i) {
      const Eigen::Vector2d a = l[i], b = l[(i + 1) % l.size()];
      const double t = std::clamp((q - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * (b - a) - q).squaredNorm());
    }
  return std::sqrt(best);
}

}  // namespace

Result<Hausdorff> hausdorff_3d(const TriangleMesh& a, const TriangleMesh& b, const Balls3& excluded,
                               const HausdorffOptions& options) {
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance da, geometry::MeshDistance::build(a));
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance db, geometry::MeshDistance::build(b));
  Hausdorff h;
  for (int which = 0; which < 2; ++which) {
    HC_ASSIGN_OR_RETURN(
        std::vector<Eigen::Vector3d> pts,
        uniform_surface_points(which == 0 ? a : b, options.samples, options.seed + which));
    HC_ASSIGN_OR_RETURN(std::vector<std::uint8_t> skip,
                        near_balls<3>(excluded, options.margin, pts, geometry::nearest_power_3d));
    double worst = 0.0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (skip[i]) {
        ++h.excluded;
        continue;
      }
      worst = std::max(worst, (which == 0 ? db : da).distance(pts[i]));
    }
    (which == 0 ? h.a_to_b : h.b_to_a) = worst;
  }
  return h;
}

Result<Hausdorff> hausdorff_2d(const Polygon2& a, const Polygon2& b, const Balls2& excluded,
                               const HausdorffOptions& options) {
  Hausdorff h;
  std::mt19937_64 rng(options.seed);
  for (int which = 0; which < 2; ++which) {
    const std::vector<Eigen::Vector2d> pts =
        outline_points(which == 0 ? a : b, options.samples / 10, rng);
    HC_ASSIGN_OR_RETURN(std::vector<std::uint8_t> skip,
                        near_balls<2>(excluded, options.margin, pts, geometry::nearest_power_2d));
    double worst = 0.0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (skip[i]) {
        ++h.excluded;
        continue;
      }
      worst = std::max(worst, distance_to_outline(which == 0 ? b : a, pts[i]));
    }
    (which == 0 ? h.a_to_b : h.b_to_a) = worst;
  }
  return h;
}

}  // namespace hc::abstraction
