// Regular (and Delaunay) triangulations in 3-D: CGAL's Regular_triangulation_3 on the Epick kernel
// (exact predicates). One instantiation serves both: the Delaunay triangulation is the regular one
// with zero weights. Power vertices are constructed in double: the exact fallback of CGAL's
// robust circumcentre traits (Robust_weighted_circumcenter_filtered_traits_3) was tried and is
// unusable here, because a power crust is degenerate by design (every sample is the power vertex
// of all the cells of the balls through it), so nearly every cell fell back to GMP rationals
// (a 1 x 1 x 1 cube at r_min 0.01 ran for over 10 minutes). The crust merges the power vertices
// that rounding left a few ulps apart instead (power_crust.h).
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_3.h>
#include <CGAL/Regular_triangulation_cell_base_3.h>
#include <CGAL/Regular_triangulation_vertex_base_3.h>
#include <CGAL/Spatial_lock_grid_3.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <utility>

#include "cgal_support.h"
#include "geometry/regular_triangulation.h"

namespace hc::geometry {
namespace {

using internal::guarded;

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Gt = K;
using Vb0 = CGAL::Regular_triangulation_vertex_base_3<Gt>;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int, Gt, Vb0>;
// Hidden points are not kept: the medial-ball code only needs which points became vertices. The
// cell's info is its index in the output.
using Cb0 = CGAL::Regular_triangulation_cell_base_3<Gt, CGAL::Triangulation_cell_base_3<Gt>,
                                                    CGAL::Discard_hidden_points>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int, Gt, Cb0>;
// The concurrent data structure: large inputs are inserted in parallel (TBB) under a grid of
// spatial locks; without a lock grid the same type inserts sequentially.
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb, CGAL::Parallel_tag>;
using Lock = CGAL::Spatial_lock_grid_3<CGAL::Tag_priority_blocking>;
using Rt = CGAL::Regular_triangulation_3<Gt, Tds, Lock>;
// Below this many points the parallel insertion's set-up costs more than it saves.
constexpr std::size_t kParallelFrom = 20'000;
bool large(std::size_t points) { return points >= kParallelFrom; }
using WPoint = Gt::Weighted_point_3;
using BPoint = Gt::Point_3;
// The parallel insertion only pays on idle cores: its threads wait for each other's spatial locks,
// so a lock holder preempted by another process stalls the rest. Measured on 2 cores
// (bench_abstraction fandisk.off, 596,637 balls): 2.5 s parallel / 3.6 s sequential on an idle
// machine; with two busy processes beside it 6-20 s parallel against 5.4 s sequential (the
// 100k-point Delaunay 0.36 -> 6.5 s). So kAuto inserts in parallel only while no other thread is
// runnable on the core it would take: Linux's instantaneous count of runnable threads
// (/proc/stat procs_running, this one included; the median of three reads 2 ms apart) at most
// cores - 1. The 1-minute load average would lag, and count this process's own parallel phases.
// Where /proc/stat cannot be read, parallel.
int runnable_threads() {
  std::array<int, 3> reads{};
  for (std::size_t i = 0; i < reads.size(); ++i) {
    if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    int running = -1;
    std::ifstream in("/proc/stat");
    std::string key;
    while (in >> key) {
      if (key == "procs_running") {
        in >> running;
        break;
      }
      in.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
    }
    if (running < 0) return -1;
    reads[i] = running;
  }
  std::sort(reads.begin(), reads.end());
  return reads[1];
}

bool parallel(std::size_t points, Insertion insertion) {
  if (!large(points) || insertion == Insertion::kSequential) return false;
  if (insertion == Insertion::kParallel) return true;
  const int cores = static_cast<int>(std::thread::hardware_concurrency());
  if (cores < 2) return false;
  const int runnable = runnable_threads();
  return runnable < 0 || runnable <= cores - 1;
}

Status check_input(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                   std::string_view what) {
  if (!weights.empty() && weights.size() != points.size()) {
    return invalid_argument(
        fmt::format("{}: {} points but {} weights", what, points.size(), weights.size()));
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite() || (!weights.empty() && !std::isfinite(weights[i]))) {
      return invalid_argument(fmt::format("{}: point {} is not finite", what, i));
    }
  }
  return {};
}

Status build_rt(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                std::string_view what, Insertion insertion, Rt* rt) {
  HC_RETURN_IF_ERROR(check_input(points, weights, what));
  std::vector<std::pair<WPoint, int>> input;
  input.reserve(points.size());
  CGAL::Bbox_3 box;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights.empty() ? 0.0 : weights[i];
    input.emplace_back(WPoint(BPoint(points[i].x(), points[i].y(), points[i].z()), w),
                       static_cast<int>(i));
    box += input.back().first.bbox();
  }
  // The range insertion sorts the points along a Hilbert curve first (spatial_sort). The
  // triangulation does not depend on the insertion order (the perturbation of degenerate
  // predicates is symbolic), so the parallel insertion gives the same cells, in another order.
  std::unique_ptr<Lock> lock;
  if (parallel(points.size(), insertion)) lock = std::make_unique<Lock>(box, 50);
  rt->set_lock_data_structure(lock.get());
  rt->insert(input.begin(), input.end());
  rt->set_lock_data_structure(nullptr);
  return {};
}

// An even permutation of a cell's corners that puts the smallest index first and, of the three
// rotations of the rest, the smallest second: every cell gets one spelling whatever the insertion
// order (an infinite cell, whose -1 is smallest, too).
std::array<int, 4> canonical_order(const std::array<int, 4>& v) {
  static constexpr int kEven[12][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 0, 3, 2},
                                       {1, 2, 0, 3}, {1, 3, 2, 0}, {2, 0, 1, 3}, {2, 1, 3, 0},
                                       {2, 3, 0, 1}, {3, 0, 2, 1}, {3, 1, 0, 2}, {3, 2, 1, 0}};
  std::array<int, 4> best{0, 1, 2, 3};
  bool first = true;
  for (const auto& p : kEven) {
    const std::array<int, 4> cand{v[static_cast<std::size_t>(p[0])],
                                  v[static_cast<std::size_t>(p[1])],
                                  v[static_cast<std::size_t>(p[2])],
                                  v[static_cast<std::size_t>(p[3])]};
    const std::array<int, 4> cur{v[static_cast<std::size_t>(best[0])],
                                 v[static_cast<std::size_t>(best[1])],
                                 v[static_cast<std::size_t>(best[2])],
                                 v[static_cast<std::size_t>(best[3])]};
    if (first || cand < cur) best = {p[0], p[1], p[2], p[3]};
    first = false;
  }
  return best;
}

}  // namespace

Result<Triangulation3> triangulate_3d(std::span<const Eigen::Vector3d> points,
                                      std::span<const double> weights, Insertion insertion) {
  constexpr std::string_view kWhat = "triangulate_3d";
  return guarded<Triangulation3>(kWhat, [&]() -> Result<Triangulation3> {
    Rt rt;
    HC_RETURN_IF_ERROR(build_rt(points, weights, kWhat, insertion, &rt));
    if (rt.dimension() < 3) {
      return invalid_argument(fmt::format("{}: the {} points span only {} dimension(s); 3 needed",
                                          kWhat, points.size(),
                                          rt.dimension() < 0 ? 0 : rt.dimension()));
    }
    Triangulation3 out;
    out.is_vertex.assign(points.size(), 0);
    for (auto v = rt.finite_vertices_begin(); v != rt.finite_vertices_end(); ++v) {
      out.is_vertex[static_cast<std::size_t>(v->info())] = 1;
    }
    // Large inputs' cells are put in a canonical order (sorted by their canonical corner
    // spelling), so the output is the same whichever order the threads left them in, and the same
    // whether the insertion ran in parallel or not; a small input's sequential order is
    // deterministic already and is kept (the crust's triangulation of each power face starts at
    // its first cell, so reordering changes output).
    struct Entry {
      std::array<int, 4> corners;  // canonical spelling (for large inputs)
      std::array<int, 4> perm;     // corners[k] = CGAL's vertex perm[k]
      Rt::Cell_handle cell;
    };
    const bool sort = large(points.size());
    std::vector<Entry> cells;
    cells.reserve(rt.number_of_cells());
    for (auto c = rt.all_cells_begin(); c != rt.all_cells_end(); ++c) {
      std::array<int, 4> v;
      for (int k = 0; k < 4; ++k) {
        const auto h = c->vertex(k);
        v[static_cast<std::size_t>(k)] = rt.is_infinite(h) ? -1 : h->info();
      }
      const std::array<int, 4> p =
          sort ? canonical_order(v) : std::array<int, 4>{0, 1, 2, 3};
      cells.push_back({{v[static_cast<std::size_t>(p[0])], v[static_cast<std::size_t>(p[1])],
                        v[static_cast<std::size_t>(p[2])], v[static_cast<std::size_t>(p[3])]},
                       p,
                       c});
    }
    if (sort) {
      tbb::parallel_sort(cells.begin(), cells.end(),
                         [](const Entry& a, const Entry& b) { return a.corners < b.corners; });
    }
    const std::size_t n = cells.size();
    for (std::size_t i = 0; i < n; ++i) cells[i].cell->info() = static_cast<int>(i);
    out.cells.resize(n);
    out.neighbours.resize(n);
    out.centres.assign(n, Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    out.squared_radii.assign(n, std::numeric_limits<double>::quiet_NaN());
    const auto centre = rt.geom_traits().construct_weighted_circumcenter_3_object();
    const auto radius =
        rt.geom_traits().compute_squared_radius_smallest_orthogonal_sphere_3_object();
    // Cell by cell, independent: in parallel.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        const Entry& e = cells[i];
        const Rt::Cell_handle c = e.cell;
        out.cells[i] = e.corners;
        for (std::size_t k = 0; k < 4; ++k) out.neighbours[i][k] = c->neighbor(e.perm[k])->info();
        if (e.corners[0] < 0) continue;  // infinite
        const WPoint& p = c->vertex(e.perm[0])->point();
        const WPoint& q = c->vertex(e.perm[1])->point();
        const WPoint& r = c->vertex(e.perm[2])->point();
        const WPoint& s = c->vertex(e.perm[3])->point();
        const BPoint o = centre(p, q, r, s);
        out.centres[i] = Eigen::Vector3d(o.x(), o.y(), o.z());
        out.squared_radii[i] = CGAL::to_double(radius(p, q, r, s));
      }
    });
    return out;
  });
}

Result<PowerQuery> nearest_power_3d(std::span<const Eigen::Vector3d> centres,
                                    std::span<const double> weights,
                                    std::span<const Eigen::Vector3d> queries) {
  constexpr std::string_view kWhat = "nearest_power_3d";
  return guarded<PowerQuery>(kWhat, [&]() -> Result<PowerQuery> {
    if (centres.empty() || weights.size() != centres.size()) {
      return invalid_argument(
          fmt::format("{}: {} balls with {} weights", kWhat, centres.size(), weights.size()));
    }
    Rt rt;
    HC_RETURN_IF_ERROR(build_rt(centres, weights, kWhat, Insertion::kAuto, &rt));
    PowerQuery out;
    out.power.resize(queries.size());
    out.ball.resize(queries.size());
    Rt::Cell_handle hint;
    for (std::size_t i = 0; i < queries.size(); ++i) {
      if (!queries[i].allFinite()) {
        return invalid_argument(fmt::format("{}: query {} is not finite", kWhat, i));
      }
      const BPoint q(queries[i].x(), queries[i].y(), queries[i].z());
      const auto v = rt.nearest_power_vertex(q, hint);
      hint = v->cell();
      const int b = v->info();
      out.ball[i] = b;
      out.power[i] = (queries[i] - centres[static_cast<std::size_t>(b)]).squaredNorm() -
                     weights[static_cast<std::size_t>(b)];
    }
    return out;
  });
}

}  // namespace hc::geometry
