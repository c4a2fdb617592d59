// 3-D abstraction by pockets (abstraction.h): the exterior region a rolling ball of radius rho
// cannot reach, cut into connected pockets on the regular triangulation of the balls, each
// measured by its width (largest ball) and mean depth (power-cell volume / lid area).
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <chrono>
#include <cmath>
#include <numeric>
#include <unordered_set>

#include "common/clock.h"
#include "fabrication/abstraction/abstraction.h"
#include "geometry/regular_triangulation.h"

namespace hc::abstraction {
namespace {

int find(std::vector<int>& p, int x) {
  while (p[static_cast<std::size_t>(x)] != x) {
    p[static_cast<std::size_t>(x)] = p[static_cast<std::size_t>(p[static_cast<std::size_t>(x)])];
    x = p[static_cast<std::size_t>(x)];
  }
  return x;
}

struct PocketMeasure {
  double volume = 0.0;  // sum of the pocket's power cells (divergence theorem over its faces)
  double lid = 0.0;     // area of the faces towards exterior balls left outside
};

}  // namespace

Result<std::vector<Intrusion>> abstract_balls_3d(const AbstractionOptions& options, Balls3* balls,
                                                 double r_min) {
  HC_RETURN_IF_ERROR(options.validate());
  const double rho = (1.0 - options.width_tolerance) * 0.5 * options.feature_size;
  const std::size_t n = balls->size();
  const std::vector<double> w = power_weights(*balls);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation3 rt, geometry::triangulate_3d(balls->centres, w));
  // Open balls: exterior, narrow, a vertex of the triangulation, centre outside every wide
  // exterior ball.
  std::vector<Eigen::Vector3d> wide_c, narrow_c;
  std::vector<double> wide_w;
  std::vector<int> narrow_i;
  for (std::size_t i = 0; i < n; ++i) {
    if (balls->interior[i] || !rt.is_vertex[i]) continue;
    if (balls->radii[i] >= rho) {
      wide_c.push_back(balls->centres[i]);
      wide_w.push_back(w[i]);
    } else {
      narrow_c.push_back(balls->centres[i]);
      narrow_i.push_back(static_cast<int>(i));
    }
  }
  std::vector<std::uint8_t> open(n, 0);
  if (narrow_i.empty()) return std::vector<Intrusion>{};
  if (!wide_c.empty()) {
    HC_ASSIGN_OR_RETURN(geometry::PowerQuery q,
                        geometry::nearest_power_3d(wide_c, wide_w, narrow_c));
    for (std::size_t k = 0; k < narrow_i.size(); ++k)
      open[static_cast<std::size_t>(narrow_i[k])] = q.power[k] >= 0;
  } else {
    for (const int i : narrow_i) open[static_cast<std::size_t>(i)] = 1;
  }
  // Pockets: open balls joined by triangulation edges.
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (std::size_t c = 0; c < rt.cells.size(); ++c) {
    if (!rt.is_finite(static_cast<int>(c))) continue;
    const auto& cell = rt.cells[c];
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        const int a = cell[static_cast<std::size_t>(i)], b = cell[static_cast<std::size_t>(j)];
        if (open[static_cast<std::size_t>(a)] && open[static_cast<std::size_t>(b)]) {
          parent[static_cast<std::size_t>(find(parent, a))] = find(parent, b);
        }
      }
    }
  }
  // Measures: every face between a pocket ball and a ball outside the pocket.
  std::vector<PocketMeasure> measure(n);
  std::unordered_set<std::uint64_t> done;
  for (std::size_t c = 0; c < rt.cells.size(); ++c) {
    if (!rt.is_finite(static_cast<int>(c))) continue;
    const auto& cell = rt.cells[c];
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) {
        const int a = cell[static_cast<std::size_t>(i)], b = cell[static_cast<std::size_t>(j)];
        if (i == j || !open[static_cast<std::size_t>(a)] || open[static_cast<std::size_t>(b)])
          continue;
        const auto lo = static_cast<std::uint32_t>(a), hi = static_cast<std::uint32_t>(b);
        if (!done.insert((std::uint64_t{lo} << 32) | hi).second) continue;
        auto ring = power_face(rt, static_cast<int>(c), a, b);
        if (!ring.ok()) continue;  // an unbounded face: only far exterior balls have those
        const Eigen::Vector3d& p0 = rt.centres[static_cast<std::size_t>(ring->front())];
        Eigen::Vector3d s = Eigen::Vector3d::Zero();  // vector area, pointing from a to b
        for (std::size_t k = 1; k + 1 < ring->size(); ++k) {
          s += 0.5 * (rt.centres[static_cast<std::size_t>((*ring)[k])] - p0)
                         .cross(rt.centres[static_cast<std::size_t>((*ring)[k + 1])] - p0);
        }
        PocketMeasure& m = measure[static_cast<std::size_t>(find(parent, a))];
        m.volume += s.dot(p0) / 3.0;
        if (!balls->interior[static_cast<std::size_t>(b)]) m.lid += s.norm();
      }
    }
  }
  // Group, measure, decide.
  std::vector<std::vector<int>> members(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (open[i])
      members[static_cast<std::size_t>(find(parent, static_cast<int>(i)))].push_back(
          static_cast<int>(i));
  }
  std::vector<Intrusion> out;
  const double min_size = options.min_pocket_size * r_min;
  for (std::size_t root = 0; root < n; ++root) {
    const auto& mem = members[root];
    if (mem.empty()) continue;
    const PocketMeasure& m = measure[root];
    if (!(m.lid > 0) || !(m.volume > 0) || std::cbrt(m.volume) < min_size) continue;
    Intrusion in;
    double r_max = 0.0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const int i : mem) {
      r_max = std::max(r_max, balls->radii[static_cast<std::size_t>(i)]);
      mean += balls->centres[static_cast<std::size_t>(i)];
    }
    mean /= static_cast<double>(mem.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const int i : mem) {
      const Eigen::Vector3d d = balls->centres[static_cast<std::size_t>(i)] - mean;
      cov += d * d.transpose();
    }
    cov /= static_cast<double>(mem.size());
    const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues();
    in.centre = mean;
    in.width = 2.0 * r_max;
    in.depth = m.volume / m.lid;
    in.ratio = in.depth / in.width;
    in.balls = mem.size();
    // Second-largest principal extent against the width: a curve's balls line up, a sheet's spread.
    in.medial_part = std::sqrt(std::max(ev[1], 0.0)) > 0.5 * in.width ? "sheet" : "curve";
    in.closed = in.ratio > options.depth_ratio;
    if (in.closed) {
      for (const int i : mem) balls->interior[static_cast<std::size_t>(i)] = 1;
    }
    out.push_back(in);
  }
  return out;
}

Result<AbstractionResult<TriangleMesh, 3>> abstract_3d(const TriangleMesh& mesh,
                                                       const AbstractionOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  AbstractionResult<TriangleMesh, 3> result;
  auto& sum = result.summary;
  HC_ASSIGN_OR_RETURN(Balls3 balls, mesh_balls(mesh, options.shape, &sum));
  const std::vector<std::uint8_t> before = balls.interior;
  HC_ASSIGN_OR_RETURN(result.intrusions, abstract_balls_3d(options, &balls, sum.sampling.r_min));
  for (std::size_t i = 0; i < balls.size(); ++i) {
    if (balls.interior[i] && !before[i])
      result.closed.push_back(balls.centres[i], balls.radii[i], true);
  }
  for (const auto& i : result.intrusions)
    (i.closed ? sum.intrusions_closed : sum.intrusions_kept)++;
  HC_ASSIGN_OR_RETURN(result.shape, power_crust_3d(balls, &sum.crust));
  sum.time_s = seconds_since(t0);
  return result;
}

}  // namespace hc::abstraction
