#include "fabrication/articulation/joint_locations.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <queue>
#include <utility>

namespace hc::articulation {

std::vector<int> segment_by_max_weight(const Eigen::MatrixXd& weights) {
  std::vector<int> out(static_cast<std::size_t>(weights.rows()));
  for (Eigen::Index v = 0; v < weights.rows(); ++v) {
    Eigen::Index best = 0;
    weights.row(v).maxCoeff(&best);
    out[static_cast<std::size_t>(v)] = static_cast<int>(best);
  }
  return out;
}

Status TransitionOptions::validate() const {
  if (!(degenerate_ratio >= 1) || !std::isfinite(degenerate_ratio))
    return invalid_argument(
        fmt::format("degenerate ratio f must be >= 1, got {}", degenerate_ratio));
  if (min_points < 3) return invalid_argument("min_points must be >= 3");
  return {};
}

Result<std::vector<Transition>> find_transitions(const TriangleMesh& mesh,
                                                 const Eigen::MatrixXd& weights,
                                                 const std::vector<int>& link_parent,
                                                 const std::vector<int>& link_depth,
                                                 const TransitionOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  if (weights.rows() != mesh.num_vertices())
    return invalid_argument(fmt::format("transitions: {} weight rows for {} vertices",
                                        weights.rows(), mesh.num_vertices()));
  if (link_parent.size() != static_cast<std::size_t>(weights.cols()) ||
      link_depth.size() != link_parent.size())
    return invalid_argument("transitions: link tree and weight columns differ");
  const std::vector<int> label = segment_by_max_weight(weights);
  // Unique undirected edges.
  std::vector<std::pair<int, int>> edges;
  edges.reserve(static_cast<std::size_t>(3 * mesh.num_triangles()));
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.triangles(t, k), b = mesh.triangles(t, (k + 1) % 3);
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());

  struct Accum {
    std::vector<Eigen::Vector3d> points, m_ends, o_ends;
  };
  std::map<std::pair<int, int>, Accum> by_pair;
  for (auto [j, k] : edges) {
    const int lj = label[static_cast<std::size_t>(j)], lk = label[static_cast<std::size_t>(k)];
    if (lj == lk) continue;
    const bool j_first =
        link_depth[static_cast<std::size_t>(lj)] < link_depth[static_cast<std::size_t>(lk)] ||
        (link_depth[static_cast<std::size_t>(lj)] == link_depth[static_cast<std::size_t>(lk)] &&
         lj < lk);
    const int m = j_first ? lj : lk, o = j_first ? lk : lj;
    const Eigen::Vector3d vj = mesh.vertices.row(j), vk = mesh.vertices.row(k);
    const double wj = weights(j, lj), wk = weights(k, lk);
    Accum& acc = by_pair[{m, o}];
    acc.points.push_back((wj * vj + wk * vk) / (wj + wk));  // Eq. 6.3
    acc.m_ends.push_back(j_first ? vj : vk);
    acc.o_ends.push_back(j_first ? vk : vj);
  }

  std::vector<Transition> out;
  for (auto& [pair, acc] : by_pair) {
    Transition t;
    t.parent_link = pair.first;
    t.child_link = pair.second;
    t.tree_edge = link_parent[static_cast<std::size_t>(pair.second)] == pair.first;
    t.points = std::move(acc.points);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : t.points) mean += p;
    mean /= static_cast<double>(t.points.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : t.points) cov += (p - mean) * (p - mean).transpose();
    cov /= static_cast<double>(t.points.size());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    t.centre = mean;
    t.lambdas = eig.eigenvalues().cwiseMax(0.0);
    t.normal = eig.eigenvectors().col(0);
    t.major = eig.eigenvectors().col(2);
    t.ratio =
        t.lambdas(1) > 0 ? t.lambdas(2) / t.lambdas(1) : std::numeric_limits<double>::infinity();
    t.degenerate = static_cast<int>(t.points.size()) < options.min_points ||
                   t.ratio > options.degenerate_ratio;
    // Orient root -> leaves: the child link's ends on the positive side, the parent's negative.
    double score = 0.0;
    for (std::size_t i = 0; i < acc.m_ends.size(); ++i) {
      score += (acc.o_ends[i] - mean).dot(t.normal) > 0 ? 1 : -1;
      score -= (acc.m_ends[i] - mean).dot(t.normal) > 0 ? 1 : -1;
    }
    if (score < 0) t.normal = -t.normal;
    out.push_back(std::move(t));
  }
  return out;
}

MedialCentre medial_centre(const Eigen::Vector3d& centre, const Eigen::Vector3d& normal,
                           double search_radius,
                           const std::function<double(const Eigen::Vector3d&)>& depth) {
  MedialCentre out;
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d u = n.unitOrthogonal(), w = n.cross(u);
  constexpr int kGrid = 25;
  const double cell = 2 * search_radius / (kGrid - 1);
  const auto at = [&](double x, double y) { return Eigen::Vector3d(centre + x * u + y * w); };
  std::vector<double> d(kGrid * kGrid, -std::numeric_limits<double>::infinity());
  int seed = -1;
  double seed_dist = std::numeric_limits<double>::infinity();
  for (int i = 0; i < kGrid; ++i)
    for (int j = 0; j < kGrid; ++j) {
      const double x = -search_radius + i * cell, y = -search_radius + j * cell;
      if (std::hypot(x, y) > search_radius) continue;
      const double v = depth(at(x, y));
      d[static_cast<std::size_t>(i * kGrid + j)] = v;
      if (v > 0 && std::hypot(x, y) < seed_dist) seed_dist = std::hypot(x, y), seed = i * kGrid + j;
    }
  if (seed < 0) return out;
  // The inside region connected to the seed (4-neighbours), and its deepest cell.
  std::vector<char> seen(d.size(), 0);
  std::queue<int> queue;
  queue.push(seed);
  seen[static_cast<std::size_t>(seed)] = 1;
  int best = seed;
  while (!queue.empty()) {
    const int c = queue.front();
    queue.pop();
    if (d[static_cast<std::size_t>(c)] > d[static_cast<std::size_t>(best)]) best = c;
    const int i = c / kGrid, j = c % kGrid;
    const int nb[4][2] = {{i - 1, j}, {i + 1, j}, {i, j - 1}, {i, j + 1}};
    for (const auto& q : nb) {
      if (q[0] < 0 || q[0] >= kGrid || q[1] < 0 || q[1] >= kGrid) continue;
      const int k = q[0] * kGrid + q[1];
      if (seen[static_cast<std::size_t>(k)] || !(d[static_cast<std::size_t>(k)] > 0)) continue;
      seen[static_cast<std::size_t>(k)] = 1;
      queue.push(k);
    }
  }
  // Pattern search in the plane from the deepest cell.
  double x = -search_radius + (best / kGrid) * cell, y = -search_radius + (best % kGrid) * cell;
  double value = d[static_cast<std::size_t>(best)];
  for (double step = cell / 2; step > cell / 4096; step /= 2) {
    bool moved = true;
    while (moved) {
      moved = false;
      for (const auto& s : {std::pair{step, 0.0}, {-step, 0.0}, {0.0, step}, {0.0, -step}}) {
        const double nx = x + s.first, ny = y + s.second;
        if (std::hypot(nx, ny) > search_radius) continue;
        const double v = depth(at(nx, ny));
        if (v > value) x = nx, y = ny, value = v, moved = true;
      }
    }
  }
  out.found = true;
  out.centre = at(x, y);
  out.r_max = value;
  return out;
}

}  // namespace hc::articulation
