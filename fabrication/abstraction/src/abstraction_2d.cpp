// 2-D abstraction as the thesis did it (abstraction.h): bridges of the exterior medial-axis graph,
// the trees they form, and the rate of change of the radius along every branch.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <deque>

#include "common/clock.h"
#include "fabrication/abstraction/abstraction.h"
#include "geometry/triangulation_2d.h"

namespace hc::abstraction {
namespace {

using Graph = std::vector<std::vector<int>>;

// Bridges of an undirected graph (Tarjan 1974), iteratively: is_bridge[v][k] for edge v-adj[v][k].
std::vector<std::vector<std::uint8_t>> bridges(const Graph& g) {
  const std::size_t n = g.size();
  std::vector<int> order(n, -1), low(n, 0);
  std::vector<std::vector<std::uint8_t>> is_bridge(n);
  for (std::size_t v = 0; v < n; ++v) is_bridge[v].assign(g[v].size(), 0);
  int counter = 0;
  struct Frame {
    int v, parent_edge_from;
    std::size_t next;
  };
  for (std::size_t root = 0; root < n; ++root) {
    if (order[root] >= 0) continue;
    std::vector<Frame> stack{{static_cast<int>(root), -1, 0}};
    order[root] = low[root] = counter++;
    while (!stack.empty()) {
      Frame& f = stack.back();
      const auto v = static_cast<std::size_t>(f.v);
      if (f.next < g[v].size()) {
        const int w = g[v][f.next++];
        if (w == f.parent_edge_from) continue;  // the tree edge back to the parent (simple graph)
        const auto wi = static_cast<std::size_t>(w);
        if (order[wi] < 0) {
          order[wi] = low[wi] = counter++;
          stack.push_back({w, f.v, 0});
        } else {
          low[v] = std::min(low[v], order[wi]);
        }
        continue;
      }
      const int child = f.v, parent = f.parent_edge_from;
      stack.pop_back();
      if (parent < 0) continue;
      const auto p = static_cast<std::size_t>(parent);
      low[p] = std::min(low[p], low[static_cast<std::size_t>(child)]);
      if (low[static_cast<std::size_t>(child)] > order[p]) {
        for (std::size_t k = 0; k < g[p].size(); ++k) {
          if (g[p][k] == child) is_bridge[p][k] = 1;
        }
        const auto c = static_cast<std::size_t>(child);
        for (std::size_t k = 0; k < g[c].size(); ++k) {
          if (g[c][k] == parent) is_bridge[c][k] = 1;
        }
      }
    }
  }
  return is_bridge;
}

}  // namespace

Status AbstractionOptions::validate() const {
  if (!(feature_size > 0) || !std::isfinite(feature_size)) {
    return invalid_argument(
        fmt::format("abstraction: the feature size must be > 0, got {}", feature_size));
  }
  if (!(depth_ratio > 0)) return invalid_argument("abstraction: the depth ratio tau must be > 0");
  if (!(width_tolerance >= 0 && width_tolerance < 1)) {
    return invalid_argument("abstraction: width_tolerance must be in [0, 1)");
  }
  if (!(slow_rate > 0 && slow_rate < 1))
    return invalid_argument("abstraction: slow_rate must be in (0, 1)");
  if (!(min_pocket_size >= 0)) return invalid_argument("abstraction: min_pocket_size must be >= 0");
  return shape.validate();
}

Result<std::vector<Intrusion>> abstract_balls_2d(const AbstractionOptions& options, Balls2* balls) {
  HC_RETURN_IF_ERROR(options.validate());
  const double rho = (1.0 - options.width_tolerance) * 0.5 * options.feature_size;
  const std::size_t n = balls->size();
  if (balls->neighbours.size() != n)
    return invalid_argument("abstraction: balls without a medial graph");
  // The exterior graph, in exterior-ball indices.
  std::vector<int> local(n, -1), global;
  for (std::size_t i = 0; i < n; ++i) {
    if (!balls->interior[i]) {
      local[i] = static_cast<int>(global.size());
      global.push_back(static_cast<int>(i));
    }
  }
  Graph g(global.size());
  for (std::size_t k = 0; k < global.size(); ++k) {
    for (const int nb : balls->neighbours[static_cast<std::size_t>(global[k])]) {
      if (nb >= 0 && local[static_cast<std::size_t>(nb)] >= 0)
        g[k].push_back(local[static_cast<std::size_t>(nb)]);
    }
  }
  const auto is_bridge = bridges(g);
  // Cycle vertices: on a non-bridge edge. Trees: BFS from them over bridges gives each tree
  // vertex its parent towards the cycle. (A component without a cycle cannot occur: the bounded
  // exterior always surrounds the shape; its vertices would simply stay unvisited.)
  std::vector<int> parent(g.size(), -2);  // -2 unvisited, -1 root
  std::deque<int> queue;
  for (std::size_t v = 0; v < g.size(); ++v) {
    for (std::size_t k = 0; k < g[v].size(); ++k) {
      if (!is_bridge[v][k] && parent[v] == -2) {
        parent[v] = -1;
        queue.push_back(static_cast<int>(v));
      }
    }
  }
  const auto r = [&](int v) {
    return balls->radii[static_cast<std::size_t>(global[static_cast<std::size_t>(v)])];
  };
  const auto c = [&](int v) {
    return balls->centres[static_cast<std::size_t>(global[static_cast<std::size_t>(v)])];
  };
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop_front();
    for (const int w : g[static_cast<std::size_t>(v)]) {
      if (parent[static_cast<std::size_t>(w)] == -2) {
        parent[static_cast<std::size_t>(w)] = v;
        queue.push_back(w);
      }
    }
  }
  // Wide balls and which narrow centres they cover (the rolling ball's reach).
  std::vector<Eigen::Vector2d> wide_c, narrow_c;
  std::vector<double> wide_w;
  std::vector<int> narrow_v;
  for (std::size_t v = 0; v < g.size(); ++v) {
    if (r(static_cast<int>(v)) >= rho) {
      wide_c.push_back(c(static_cast<int>(v)));
      wide_w.push_back(r(static_cast<int>(v)) * r(static_cast<int>(v)));
    } else {
      narrow_c.push_back(c(static_cast<int>(v)));
      narrow_v.push_back(static_cast<int>(v));
    }
  }
  std::vector<std::uint8_t> open(g.size(), 0);  // narrow and not covered
  if (!wide_c.empty() && !narrow_c.empty()) {
    HC_ASSIGN_OR_RETURN(geometry::PowerQuery2 q,
                        geometry::nearest_power_2d(wide_c, wide_w, narrow_c));
    for (std::size_t i = 0; i < narrow_v.size(); ++i)
      open[static_cast<std::size_t>(narrow_v[i])] = q.power[i] >= 0;
  } else {
    for (const int v : narrow_v) open[static_cast<std::size_t>(v)] = 1;
  }
  std::vector<std::vector<int>> children(g.size());
  for (std::size_t v = 0; v < g.size(); ++v) {
    if (parent[v] >= 0)
      children[static_cast<std::size_t>(parent[v])].push_back(static_cast<int>(v));
  }
  std::vector<std::uint8_t> closed(g.size(), 0), seen_top(g.size(), 0);
  std::vector<Intrusion> out;
  for (std::size_t leaf = 0; leaf < g.size(); ++leaf) {
    if (g[leaf].size() != 1 || parent[leaf] < 0 || !open[leaf]) continue;
    // Follow the branch while the balls are open (narrow, uncovered).
    std::vector<int> path{static_cast<int>(leaf)};
    while (parent[static_cast<std::size_t>(path.back())] >= 0 &&
           open[static_cast<std::size_t>(parent[static_cast<std::size_t>(path.back())])]) {
      path.push_back(parent[static_cast<std::size_t>(path.back())]);
    }
    const int top = path.back();  // the last open ball before the mouth
    double slow = 0.0, weighted_r = 0.0, r_start = -1.0;
    for (std::size_t k = 0; k + 1 < path.size(); ++k) {
      const double ds = (c(path[k + 1]) - c(path[k])).norm();
      const double dr = std::abs(r(path[k + 1]) - r(path[k]));
      if (ds <= 0 || dr >= options.slow_rate * ds) continue;
      if (r_start < 0) r_start = r(path[k]);
      slow += ds;
      weighted_r += ds * 0.5 * (r(path[k]) + r(path[k + 1]));
    }
    if (seen_top[static_cast<std::size_t>(top)]) continue;
    if (slow <= 0) continue;
    const double width = 2.0 * weighted_r / slow;
    const double depth = slow + r_start;
    Intrusion in;
    in.width = width;
    in.depth = depth;
    in.ratio = depth / width;
    in.medial_part = "branch";
    in.closed = in.ratio > options.depth_ratio;
    if (!in.closed) {
      out.push_back(in);
      continue;
    }
    seen_top[static_cast<std::size_t>(top)] = 1;
    // Close the open part of the subtree below `top`.
    std::vector<int> stack{top};
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      if (!open[static_cast<std::size_t>(v)] || closed[static_cast<std::size_t>(v)]) continue;
      closed[static_cast<std::size_t>(v)] = 1;
      sum += c(v);
      ++in.balls;
      for (const int w : children[static_cast<std::size_t>(v)]) stack.push_back(w);
    }
    if (in.balls == 0) continue;
    const Eigen::Vector2d m = sum / static_cast<double>(in.balls);
    in.centre = Eigen::Vector3d(m.x(), m.y(), 0.0);
    out.push_back(in);
  }
  for (std::size_t v = 0; v < g.size(); ++v) {
    if (closed[v]) balls->interior[static_cast<std::size_t>(global[v])] = 1;
  }
  return out;
}

Result<AbstractionResult<Polygon2, 2>> abstract_2d(const Polygon2& polygon,
                                                   const AbstractionOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  AbstractionResult<Polygon2, 2> result;
  auto& sum = result.summary;
  HC_ASSIGN_OR_RETURN(Balls2 balls, polygon_balls(polygon, options.shape, &sum));
  const std::vector<std::uint8_t> before = balls.interior;
  HC_ASSIGN_OR_RETURN(result.intrusions, abstract_balls_2d(options, &balls));
  for (std::size_t i = 0; i < balls.size(); ++i) {
    if (balls.interior[i] && !before[i])
      result.closed.push_back(balls.centres[i], balls.radii[i], true);
  }
  for (const auto& i : result.intrusions)
    (i.closed ? sum.intrusions_closed : sum.intrusions_kept)++;
  HC_ASSIGN_OR_RETURN(result.shape, power_crust_2d(balls, &sum.crust));
  sum.time_s = seconds_since(t0);
  return result;
}

}  // namespace hc::abstraction
