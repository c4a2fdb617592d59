#include "fabrication/abstraction/power_crust.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "common/clock.h"
#include "fabrication/printability/mesh_check.h"
#include "geometry/mesh_ops.h"

namespace hc::abstraction {
namespace {

// The local corner pairs of a tet: (a, b, c, d) an even permutation of (0, 1, 2, 3).
constexpr int kTetEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2},
                                 {1, 2, 0, 3}, {1, 3, 2, 0}, {2, 3, 0, 1}};

template <int D>
Status check_labels(const Balls<D>& balls) {
  std::size_t in = 0;
  for (const auto l : balls.interior) in += l;
  if (balls.size() < D + 1) return invalid_argument("power crust: too few balls");
  if (in == 0 || in == balls.size()) {
    return invalid_argument("power crust: the balls are all interior or all exterior");
  }
  return {};
}

// Cells sharing a power vertex exactly (the samples the crust interpolates) get double positions
// a few ulps apart. Vertices closer than kMergeFraction of the bounding-box diagonal are merged
// (union-find over a hash grid); triangles that lose a corner go, and pairs of opposite triangles
// on the same three vertices (a collapsed sliver pocket) cancel.
constexpr double kMergeFraction = 1e-13;
constexpr double kNoMergeRadius = 100.0;  // in merge distances
constexpr int kSnapAttempts = 4;

TriangleMesh merge_close_vertices(const std::vector<Eigen::Vector3d>& vertices,
                                  const std::vector<Eigen::Vector3i>& triangles,
                                  const std::vector<Eigen::Vector3d>& no_merge) {
  Eigen::AlignedBox3d box;
  for (const auto& v : vertices) box.extend(v);
  const double h = std::max(kMergeFraction * box.diagonal().norm(), 1e-300);
  // Vertices near a point where merging joined two sheets (power_crust_3d's retries) stay apart.
  const auto kept_apart = [&](const Eigen::Vector3d& p) {
    for (const auto& q : no_merge)
      if ((p - q).norm() <= kNoMergeRadius * h) return true;
    return false;
  };
  // A grid of cells 2h wide in an open-addressed table (cell -> first vertex, then `next`): a
  // vertex within h of p lies in p's cell or, along each axis, in the neighbour on the side of
  // the cell's middle that p is on, so 8 cells are visited.
  const double cell_size = 2.0 * h;
  const std::size_t n = vertices.size();
  std::size_t slots = 16;
  while (slots < 2 * n) slots *= 2;
  struct Slot {
    std::array<std::int64_t, 3> cell;
    int head = -1;
  };
  std::vector<Slot> table(slots);
  std::vector<int> next(n, -1);
  const auto slot_of = [&](const std::array<std::int64_t, 3>& c) -> Slot& {
    // Unsigned: the products wrap (a signed overflow is undefined).
    std::size_t i = static_cast<std::size_t>(static_cast<std::uint64_t>(c[0]) * 73856093ULL ^
                                             static_cast<std::uint64_t>(c[1]) * 19349663ULL ^
                                             static_cast<std::uint64_t>(c[2]) * 83492791ULL) &
                    (slots - 1);
    while (table[i].head >= 0 && table[i].cell != c) i = (i + 1) & (slots - 1);
    return table[i];
  };
  std::vector<int> parent(n);
  for (std::size_t i = 0; i < n; ++i) parent[i] = static_cast<int>(i);
  const auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x)
      x = parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    return x;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!no_merge.empty() && kept_apart(vertices[i])) continue;
    const Eigen::Vector3d q = vertices[i] / cell_size;
    std::array<std::int64_t, 3> c{};
    std::array<std::int64_t, 3> side{};
    for (int k = 0; k < 3; ++k) {
      const double f = std::floor(q[k]);
      c[static_cast<std::size_t>(k)] = static_cast<std::int64_t>(f);
      side[static_cast<std::size_t>(k)] = q[k] - f < 0.5 ? -1 : 1;
    }
    for (int m = 0; m < 8; ++m) {
      const std::array<std::int64_t, 3> nc{c[0] + ((m & 1) ? side[0] : 0),
                                           c[1] + ((m & 2) ? side[1] : 0),
                                           c[2] + ((m & 4) ? side[2] : 0)};
      for (int j = slot_of(nc).head; j >= 0; j = next[static_cast<std::size_t>(j)]) {
        if ((vertices[static_cast<std::size_t>(j)] - vertices[i]).norm() <= h) {
          parent[static_cast<std::size_t>(find(static_cast<int>(i)))] = find(j);
        }
      }
    }
    Slot& own = slot_of(c);
    own.cell = c;
    next[i] = own.head;
    own.head = static_cast<int>(i);
  }
  std::vector<int> index(n, -1);
  std::vector<Eigen::Vector3d> kept;
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<std::size_t>(find(static_cast<int>(i)));
    if (index[r] < 0) {
      index[r] = static_cast<int>(kept.size());
      kept.push_back(vertices[r]);
    }
  }
  // Triangles on the merged vertices; of those on the same three vertices (either orientation),
  // pairs cancel in input order, so an odd group keeps its last one.
  std::vector<Eigen::Vector3i> tris;
  std::vector<std::array<int, 3>> keys;
  tris.reserve(triangles.size());
  keys.reserve(triangles.size());
  for (const auto& t : triangles) {
    Eigen::Vector3i m;
    for (int k = 0; k < 3; ++k) m[k] = index[static_cast<std::size_t>(find(t[k]))];
    if (m[0] == m[1] || m[1] == m[2] || m[0] == m[2]) continue;
    std::array<int, 3> key{m[0], m[1], m[2]};
    std::sort(key.begin(), key.end());
    tris.push_back(m);
    keys.push_back(key);
  }
  std::vector<std::uint32_t> order(tris.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return keys[a] != keys[b] ? keys[a] < keys[b] : a < b;
  });
  std::vector<std::uint8_t> keep(tris.size(), 1);
  for (std::size_t g = 0; g < order.size();) {
    std::size_t e = g + 1;
    while (e < order.size() && keys[order[e]] == keys[order[g]]) ++e;
    for (std::size_t k = g; k + ((e - g) % 2) < e; ++k) keep[order[k]] = 0;
    g = e;
  }
  // Only the vertices a kept triangle uses, in order of first use.
  std::vector<int> used(kept.size(), -1);
  std::vector<Eigen::Vector3d> out_vertices;
  std::vector<Eigen::Vector3i> out_triangles;
  for (std::size_t t = 0; t < tris.size(); ++t) {
    if (!keep[t]) continue;
    Eigen::Vector3i u;
    for (int k = 0; k < 3; ++k) {
      int& id = used[static_cast<std::size_t>(tris[t][k])];
      if (id < 0) {
        id = static_cast<int>(out_vertices.size());
        out_vertices.push_back(kept[static_cast<std::size_t>(tris[t][k])]);
      }
      u[k] = id;
    }
    out_triangles.push_back(u);
  }
  TriangleMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(out_vertices.size()), 3);
  for (std::size_t i = 0; i < out_vertices.size(); ++i)
    mesh.vertices.row(static_cast<Eigen::Index>(i)) = out_vertices[i].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(out_triangles.size()), 3);
  for (std::size_t i = 0; i < out_triangles.size(); ++i)
    mesh.triangles.row(static_cast<Eigen::Index>(i)) = out_triangles[i].transpose();
  return mesh;
}

}  // namespace

template <int D>
std::vector<double> power_weights(const Balls<D>& balls, std::uint64_t seed) {
  std::vector<double> w(balls.size());
  for (std::size_t i = 0; i < w.size(); ++i) {
    // A fixed pseudo-random u in [0, 1) per ball (splitmix64 of its index and the seed).
    std::uint64_t z =
        (static_cast<std::uint64_t>(i) + 1 + seed * 0xD1B54A32D192ED03ULL) * 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    const double u = static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
    w[i] = balls.radii[i] * balls.radii[i] * (1.0 - kWeightPerturbation * u);
  }
  return w;
}
template std::vector<double> power_weights<2>(const Balls2&, std::uint64_t);
template std::vector<double> power_weights<3>(const Balls3&, std::uint64_t);

namespace {

// power_face into `ring` (cleared first); each cell it passes gets bit e set in done[cell] for
// the local edge e (an index into kTetEdges) that a-b is there, when `done` is given.
Status power_face_into(const geometry::Triangulation3& rt, int cell, int a, int b,
                       std::vector<int>* ring, std::vector<std::uint8_t>* done) {
  // Circulate around a->b: from a cell (a, b, c, d) positively oriented to its neighbour across
  // (a, b, d), where (a, b, d, e) is again positive; the power vertices turn counter-clockwise
  // about b - a.
  const auto& start = rt.cells[static_cast<std::size_t>(cell)];
  int ka = 0, kb = 0;
  while (start[static_cast<std::size_t>(ka)] != a) ++ka;
  while (start[static_cast<std::size_t>(kb)] != b) ++kb;
  int c = -3, d = -3;
  for (const auto& e : kTetEdges) {
    if (e[0] == ka && e[1] == kb) {
      c = start[static_cast<std::size_t>(e[2])];
      d = start[static_cast<std::size_t>(e[3])];
    } else if (e[0] == kb && e[1] == ka) {  // (b, a, c, d) even: (a, b, d, c) is
      c = start[static_cast<std::size_t>(e[3])];
      d = start[static_cast<std::size_t>(e[2])];
    }
  }
  ring->clear();
  int cur = cell;
  do {
    if (!rt.is_finite(cur)) return internal_error("power crust: an unbounded power face");
    ring->push_back(cur);
    const auto& cc = rt.cells[static_cast<std::size_t>(cur)];
    int kc = 0;
    while (cc[static_cast<std::size_t>(kc)] != c) ++kc;
    if (done) {
      // The local edge of a-b in this cell: the one whose other two corners are c and d.
      int kd = 0;
      while (cc[static_cast<std::size_t>(kd)] != d) ++kd;
      for (int e = 0; e < 6; ++e) {
        if ((kTetEdges[e][2] == kc && kTetEdges[e][3] == kd) ||
            (kTetEdges[e][2] == kd && kTetEdges[e][3] == kc)) {
          (*done)[static_cast<std::size_t>(cur)] |= static_cast<std::uint8_t>(1U << e);
        }
      }
    }
    const int nb = rt.neighbours[static_cast<std::size_t>(cur)][static_cast<std::size_t>(kc)];
    int e_new = -3;
    for (const int v : rt.cells[static_cast<std::size_t>(nb)]) {
      if (v != a && v != b && v != d) e_new = v;
    }
    c = d;
    d = e_new;
    cur = nb;
  } while (cur != cell && ring->size() <= rt.cells.size());
  if (cur != cell) return internal_error("power crust: broken edge ring");
  return {};
}

}  // namespace

Result<std::vector<int>> power_face(const geometry::Triangulation3& rt, int cell, int a, int b) {
  std::vector<int> ring;
  HC_RETURN_IF_ERROR(power_face_into(rt, cell, a, b, &ring, nullptr));
  return ring;
}

Result<Polygon2> power_crust_2d(const Balls2& balls, CrustSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(check_labels(balls));
  const std::vector<double> w = power_weights(balls);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation2 rt, geometry::triangulate_2d(balls.centres, w));
  CrustSummary sum;
  sum.balls = balls.size();
  for (const auto v : rt.is_vertex) sum.hidden_balls += v ? 0 : 1;
  // next[t]: the triangle whose power vertex follows t's on the crust (interior on the left).
  std::unordered_map<int, int> next;
  for (std::size_t t = 0; t < rt.triangles.size(); ++t) {
    const auto& tri = rt.triangles[t];
    if (!rt.is_finite(static_cast<int>(t))) continue;
    for (int k = 0; k < 3; ++k) {
      const int a = tri[static_cast<std::size_t>((k + 1) % 3)];
      const int b = tri[static_cast<std::size_t>((k + 2) % 3)];
      const bool ia = balls.interior[static_cast<std::size_t>(a)] != 0;
      const bool ib = balls.interior[static_cast<std::size_t>(b)] != 0;
      if (ia == ib || !ib) continue;  // each crust edge once: from the side where b is interior
      const int nb = rt.neighbours[t][static_cast<std::size_t>(k)];
      if (!rt.is_finite(nb)) {
        return internal_error("power crust: an interior ball's power cell is unbounded");
      }
      // Triangle t lies left of a->b; its power vertex to the neighbour's runs to the right of
      // a->b, with b (interior) on its left.
      next[static_cast<int>(t)] = nb;
      ++sum.faces;
    }
  }
  Polygon2 out;
  std::unordered_set<int> done;
  for (const auto& [start, unused] : next) {
    if (done.count(start)) continue;
    Loop2 loop;
    int t = start;
    while (!done.count(t)) {
      done.insert(t);
      const Eigen::Vector2d& p = rt.centres[static_cast<std::size_t>(t)];
      if (loop.empty() || loop.back() != p) loop.push_back(p);
      const auto it = next.find(t);
      if (it == next.end()) return internal_error("power crust: an open crust chain");
      t = it->second;
    }
    if (t != start) return internal_error("power crust: a crust vertex with more than two edges");
    while (loop.size() > 1 && loop.back() == loop.front()) loop.pop_back();
    if (loop.size() >= 3 && signed_area(loop) != 0.0) out.loops.push_back(std::move(loop));
  }
  sum.loops = out.loops.size();
  sum.vertices = out.num_points();
  sum.closed = sum.manifold = true;
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  if (out.loops.empty()) return internal_error("power crust: empty crust");
  return out;
}

namespace {

// The sample the power vertex of `cell` is, if its four balls all pass through one (see
// Balls::defining); -1 otherwise.
int shared_sample(const geometry::Triangulation3& rt, const Balls3& balls, std::size_t cell,
                  const std::vector<std::uint8_t>& no_snap) {
  if (balls.defining.size() != balls.size()) return -1;
  const auto& c = rt.cells[cell];
  int best = -1;
  double best_d = 0.0;
  for (const int s : balls.defining[static_cast<std::size_t>(c[0])]) {
    if (s < 0 || (!no_snap.empty() && no_snap[static_cast<std::size_t>(s)])) continue;
    bool all = true;
    for (std::size_t k = 1; k < 4 && all; ++k) {
      const auto& d = balls.defining[static_cast<std::size_t>(c[k])];
      all = std::find(d.begin(), d.end(), s) != d.end();
    }
    if (!all) continue;
    const double dist =
        (balls.samples[static_cast<std::size_t>(s)] - rt.centres[cell]).squaredNorm();
    if (best < 0 || dist < best_d) {
      best = s;
      best_d = dist;
    }
  }
  return best;
}

}  // namespace

// Positions where the surface is not a manifold: vertices with more than one fan of triangles,
// and the ends of edges with more than two.
std::vector<Eigen::Vector3d> non_manifold_points(const TriangleMesh& m) {
  std::unordered_map<std::uint64_t, int> edge_count;
  std::vector<std::vector<int>> around(static_cast<std::size_t>(m.num_vertices()));
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint32_t>(m.triangles(t, k));
      const auto b = static_cast<std::uint32_t>(m.triangles(t, (k + 1) % 3));
      ++edge_count[(std::uint64_t{std::min(a, b)} << 32) | std::max(a, b)];
      around[a].push_back(static_cast<int>(t));
    }
  }
  std::vector<Eigen::Vector3d> out;
  for (const auto& [key, n] : edge_count) {
    if (n <= 2) continue;
    out.push_back(m.vertices.row(static_cast<Eigen::Index>(key >> 32)).transpose());
    out.push_back(m.vertices.row(static_cast<Eigen::Index>(key & 0xffffffffULL)).transpose());
  }
  for (std::size_t v = 0; v < around.size(); ++v) {
    // Fans: the triangles around v joined through the edges at v they share.
    const auto& ts = around[v];
    std::vector<int> fan(ts.size());
    for (std::size_t i = 0; i < ts.size(); ++i) fan[i] = static_cast<int>(i);
    const auto root = [&](int x) {
      while (fan[static_cast<std::size_t>(x)] != x) x = fan[static_cast<std::size_t>(x)];
      return x;
    };
    for (std::size_t i = 0; i < ts.size(); ++i)
      for (std::size_t j = i + 1; j < ts.size(); ++j) {
        int shared = 0;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            const int va = m.triangles(ts[i], a);
            if (va != static_cast<int>(v) && va == m.triangles(ts[j], b)) ++shared;
          }
        if (shared > 0)
          fan[static_cast<std::size_t>(root(static_cast<int>(i)))] = root(static_cast<int>(j));
      }
    std::size_t fans = 0;
    for (std::size_t i = 0; i < ts.size(); ++i)
      fans += root(static_cast<int>(i)) == static_cast<int>(i);
    if (fans > 1) out.push_back(m.vertices.row(static_cast<Eigen::Index>(v)).transpose());
  }
  return out;
}

Result<TriangleMesh> crust_faces_3d(const geometry::Triangulation3& rt, const Balls3& balls,
                                    const std::vector<std::uint8_t>& no_snap,
                                    const std::vector<Eigen::Vector3d>& no_merge) {
  const auto& interior = balls.interior;
  // The crust vertex of each cell's power vertex, one per sample for those snapped to a sample.
  std::vector<int> vertex_of(rt.cells.size(), -1);
  std::vector<int> vertex_of_sample(balls.samples.size(), -1);
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  // done[c] bit e: the face of c's local edge e (kTetEdges) is made (from another cell of its
  // ring).
  std::vector<std::uint8_t> done(rt.cells.size(), 0);
  // The sample each cell between interior and exterior balls (the only ones a ring passes) snaps
  // to, found in parallel; the walk below numbers the vertices in its own order.
  std::vector<int> snap(rt.cells.size(), -1);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rt.cells.size()), [&](const auto& range) {
    for (std::size_t c = range.begin(); c != range.end(); ++c) {
      if (!rt.is_finite(static_cast<int>(c))) continue;
      const auto& cell = rt.cells[c];
      const std::uint8_t l = interior[static_cast<std::size_t>(cell[0])];
      if (interior[static_cast<std::size_t>(cell[1])] == l &&
          interior[static_cast<std::size_t>(cell[2])] == l &&
          interior[static_cast<std::size_t>(cell[3])] == l) {
        continue;
      }
      snap[c] = shared_sample(rt, balls, c, no_snap);
    }
  });
  std::vector<int> ring;
  for (std::size_t c0 = 0; c0 < rt.cells.size(); ++c0) {
    if (!rt.is_finite(static_cast<int>(c0))) continue;
    const auto& cell = rt.cells[c0];
    for (int k = 0; k < 6; ++k) {
      const auto& e = kTetEdges[k];
      const int a = cell[static_cast<std::size_t>(e[0])];
      const int b = cell[static_cast<std::size_t>(e[1])];
      if (interior[static_cast<std::size_t>(a)] == interior[static_cast<std::size_t>(b)]) continue;
      if (done[c0] & (1U << k)) continue;
      HC_RETURN_IF_ERROR(power_face_into(rt, static_cast<int>(c0), a, b, &ring, &done));
      for (const int r : ring) {
        int& v = vertex_of[static_cast<std::size_t>(r)];
        if (v >= 0) continue;
        const int s = snap[static_cast<std::size_t>(r)];
        int* at = s >= 0 ? &vertex_of_sample[static_cast<std::size_t>(s)] : &v;
        if (*at < 0) {
          *at = static_cast<int>(vertices.size());
          vertices.push_back(s >= 0 ? balls.samples[static_cast<std::size_t>(s)]
                                    : rt.centres[static_cast<std::size_t>(r)]);
        }
        v = *at;
      }
      // Outward = from the interior ball to the exterior one. Triangles that snapping collapsed
      // go here already.
      const bool forward = interior[static_cast<std::size_t>(a)] != 0;
      const int p0 = vertex_of[static_cast<std::size_t>(ring[0])];
      for (std::size_t j = 1; j + 1 < ring.size(); ++j) {
        const int p1 = vertex_of[static_cast<std::size_t>(ring[j])];
        const int p2 = vertex_of[static_cast<std::size_t>(ring[j + 1])];
        if (p0 == p1 || p1 == p2 || p0 == p2) continue;
        triangles.push_back(forward ? Eigen::Vector3i(p0, p1, p2) : Eigen::Vector3i(p0, p2, p1));
      }
    }
  }
  return merge_close_vertices(vertices, triangles, no_merge);
}

Status check_crust(double max_deviation, TriangleMesh* mesh, CrustSummary* summary) {
  fabrication::MeshCheckOptions co;
  HC_ASSIGN_OR_RETURN(fabrication::MeshCheckReport report, fabrication::check_mesh(*mesh, co));
  if (report.self_intersecting_pairs > 0 && report.closed && report.manifold) {
    geometry::ResolveOptions ro;
    ro.max_deviation = max_deviation;
    std::vector<geometry::SelfIntersectionStep> steps;
    const fabrication::MeshCheckReport before = report;
    TriangleMesh repaired = *mesh;
    HC_RETURN_IF_ERROR(geometry::resolve_self_intersections(ro, &repaired, &steps));
    HC_ASSIGN_OR_RETURN(report, fabrication::check_mesh(repaired, co));
    // The crust's intersections are rounding slivers, so a repair moves the surface by at most
    // max_deviation and the volume by at most that times the area. Autorefine, whose result need
    // only lie on its input, can instead drop whole sheets (a knot's difference once kept 1,006
    // of 444,254 triangles): such a repair is refused and the crust reported invalid.
    const double change = std::abs(report.volume - before.volume);
    if (change > max_deviation * before.area) {
      return internal_error(fmt::format(
          "power crust: repairing its {} intersecting pairs changed the volume by {:.3g} (from "
          "{:.6g}), more than the {:.3g} a surface moved by {:.3g} can",
          before.self_intersecting_pairs, change, before.volume, max_deviation * before.area,
          max_deviation));
    }
    *mesh = std::move(repaired);
    summary->repaired_pairs =
        static_cast<std::size_t>(before.self_intersecting_pairs - report.self_intersecting_pairs);
  }
  summary->closed = report.closed;
  summary->manifold = report.manifold;
  summary->self_intersecting_pairs = report.self_intersecting_pairs;
  summary->vertices = static_cast<std::size_t>(report.vertices);
  summary->triangles = static_cast<std::size_t>(report.triangles);
  if (!report.printable) {
    std::string why;
    for (const auto& p : report.problems) why += (why.empty() ? "" : "; ") + p;
    return internal_error("power crust: the reconstruction is not a valid solid: " + why);
  }
  return {};
}

namespace {

// One reconstruction with the weights perturbed by `seed` (power_weights): the triangulation, the
// crust with its snap retries, the checks.
Result<TriangleMesh> crust_with_perturbation(const Balls3& balls, std::uint64_t seed,
                                             CrustSummary* sum) {
  const std::vector<double> w = power_weights(balls, seed);
  // The crust's vertices are the power vertices of cells between interior and exterior balls.
  HC_ASSIGN_OR_RETURN(
      geometry::Triangulation3 rt,
      geometry::triangulate_3d(balls.centres, w, {.centres_between = balls.interior}));
  sum->hidden_balls = 0;
  for (const auto v : rt.is_vertex) sum->hidden_balls += v ? 0 : 1;
  TriangleMesh mesh;
  std::vector<std::uint8_t> no_snap(balls.samples.size(), 0);
  std::vector<Eigen::Vector3d> no_merge;
  // Snapping can make the crust touch itself where two sheets pass through one sample (thin
  // parts, a boolean's contact curve): those samples are left unsnapped and the crust rebuilt.
  // There the two sheets' power vertices lie within a few merge distances of each other, and
  // merging them joins the sheets again: the next attempt keeps those apart.
  for (int attempt = 0; attempt < kSnapAttempts; ++attempt) {
    HC_ASSIGN_OR_RETURN(mesh, crust_faces_3d(rt, balls, no_snap, no_merge));
    sum->faces = static_cast<std::size_t>(mesh.num_triangles());
    Eigen::AlignedBox3d box;
    for (Eigen::Index i = 0; i < mesh.num_vertices(); ++i)
      box.extend(mesh.vertices.row(i).transpose());
    const std::vector<Eigen::Vector3d> bad = non_manifold_points(mesh);
    std::size_t added = 0;
    for (const auto& p : bad) {
      bool sample = false;
      for (std::size_t s = 0; s < balls.samples.size(); ++s) {
        if (balls.samples[s] != p) continue;
        sample = true;
        if (!no_snap[s]) {
          no_snap[s] = 1;
          ++added;
        }
      }
      if (!sample && std::find(no_merge.begin(), no_merge.end(), p) == no_merge.end()) {
        no_merge.push_back(p);
        ++added;
      }
    }
    if (added > 0 && attempt + 1 < kSnapAttempts) continue;
    HC_RETURN_IF_ERROR(check_crust(1e-6 * box.diagonal().norm(), &mesh, sum));
    break;
  }
  return mesh;
}

}  // namespace

Result<TriangleMesh> power_crust_3d(const Balls3& balls, CrustSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(check_labels(balls));
  CrustSummary sum;
  sum.balls = balls.size();
  // Which power faces meet at a sample, and so whether the snapped, rounded crust is a valid
  // solid, depends on how the perturbation breaks the balls' degeneracy; where one perturbation
  // leaves the crust touching itself another usually does not, so a failed crust is rebuilt with
  // the next one (the first failure is what is reported if none succeeds).
  Status first;
  for (std::uint64_t seed = 0; seed < kPerturbations; ++seed) {
    auto mesh = crust_with_perturbation(balls, seed, &sum);
    sum.perturbations = static_cast<std::size_t>(seed) + 1;
    if (mesh.ok()) {
      sum.time_s = seconds_since(t0);
      if (summary) *summary = sum;
      return mesh;
    }
    if (mesh.status().code() != StatusCode::kInternal) return mesh.status();
    if (seed == 0) first = mesh.status();
  }
  if (summary) *summary = sum;
  return first.with_context(fmt::format("with each of {} perturbations", kPerturbations));
}

}  // namespace hc::abstraction
