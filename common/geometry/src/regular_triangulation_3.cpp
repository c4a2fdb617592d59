// Regular (and Delaunay) triangulations in 3-D: CGAL's Regular_triangulation_3 on the Epick kernel
// (exact predicates). It serves both: the Delaunay triangulation is the regular one with zero
// weights (large unweighted inputs take CGAL's Delaunay triangulation, below). Power vertices are
// constructed in double: the exact fallback of CGAL's robust circumcentre traits
// (Robust_weighted_circumcenter_filtered_traits_3) was tried and is unusable here, because a power
// crust is degenerate by design (every sample is the power vertex of all the cells of the balls
// through it), so nearly every cell fell back to GMP rationals (a 1 x 1 x 1 cube at r_min 0.01 ran
// for over 10 minutes). The crust merges the power vertices that rounding left a few ulps apart
// instead (power_crust.h).
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_3.h>
#include <CGAL/Regular_triangulation_cell_base_3.h>
#include <CGAL/Regular_triangulation_vertex_base_3.h>
#include <CGAL/Spatial_lock_grid_3.h>
#include <CGAL/Spatial_sort_traits_adapter_3.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <CGAL/hilbert_sort.h>
#include <CGAL/property_map.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <thread>
#include <type_traits>
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
using WPoint = Gt::Weighted_point_3;
// Hidden points are not kept: the medial-ball code only needs which points became vertices. With
// them discarded CGAL still puts its container of them (a std::list by default, 24 bytes) in every
// cell; this one is empty, and a cell takes 72 bytes instead of 104 (the 3.5 million cells of
// bench_abstraction's fandisk balls: 112 MB less memory to touch). CGAL reads only end() of it
// under Discard_hidden_points (Regular_triangulation_cell_base_3.h).
struct NoHiddenPoints {
  using iterator = WPoint*;
  using const_iterator = const WPoint*;
  iterator end() { return nullptr; }
  const_iterator end() const { return nullptr; }
};
// The cell's info is its index in the output.
using Cb0 = CGAL::Regular_triangulation_cell_base_3<Gt, CGAL::Triangulation_cell_base_3<Gt>,
                                                    CGAL::Discard_hidden_points, NoHiddenPoints>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int, Gt, Cb0>;
// The concurrent data structure: large inputs are inserted in parallel (TBB) under a grid of
// spatial locks; without a lock grid the same type inserts sequentially.
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb, CGAL::Parallel_tag>;
using Lock = CGAL::Spatial_lock_grid_3<CGAL::Tag_priority_blocking>;
using Rt = CGAL::Regular_triangulation_3<Gt, Tds, Lock>;
// Large unweighted inputs (the Delaunay triangulations of samples) go through CGAL's Delaunay
// triangulation instead, whose in-sphere test is cheaper than the power test with zero weights:
// the 100k fandisk samples of bench_abstraction 0.45 -> 0.38 s with the extraction. Its cells are
// the regular triangulation's (the Delaunay one is unique for points in general position), and a
// large input's output is sorted into a canonical order either way, so the output is the same
// (tested). Small inputs keep CGAL's container order, so they stay on the regular one.
using DVb = CGAL::Triangulation_vertex_base_with_info_3<int, K>;
using DCb =
    CGAL::Triangulation_cell_base_with_info_3<int, K, CGAL::Delaunay_triangulation_cell_base_3<K>>;
using DTds = CGAL::Triangulation_data_structure_3<DVb, DCb, CGAL::Parallel_tag>;
using Dt = CGAL::Delaunay_triangulation_3<K, DTds, CGAL::Default, Lock>;
// Below this many points the parallel insertion's set-up costs more than it saves.
constexpr std::size_t kParallelFrom = 20'000;
// Spatial locks per axis of the bounding box: 100 inserted the 596,637 balls of
// bench_abstraction's fandisk in 2.42 s against 2.55 s at 50 and 2.81 s at 20 (2 cores).
constexpr int kLockGrid = 100;
bool large(std::size_t points) { return points >= kParallelFrom; }
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

// T is Rt or Dt (then `weights` is empty).
template <class T>
Status build(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
             std::string_view what, Insertion insertion, T* tri) {
  HC_RETURN_IF_ERROR(check_input(points, weights, what));
  using P = typename T::Point;
  std::vector<std::pair<P, int>> input;
  input.reserve(points.size());
  CGAL::Bbox_3 box;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const BPoint b(points[i].x(), points[i].y(), points[i].z());
    if constexpr (std::is_same_v<P, WPoint>) {
      input.emplace_back(WPoint(b, weights.empty() ? 0.0 : weights[i]), static_cast<int>(i));
    } else {
      input.emplace_back(b, static_cast<int>(i));
    }
    box += b.bbox();
  }
  // The range insertion sorts the points along a Hilbert curve first (spatial_sort). The
  // triangulation does not depend on the insertion order (the perturbation of degenerate
  // predicates is symbolic), so the parallel insertion gives the same cells, in another order.
  std::unique_ptr<Lock> lock;
  if (parallel(points.size(), insertion)) lock = std::make_unique<Lock>(box, kLockGrid);
  tri->set_lock_data_structure(lock.get());
  tri->insert(input.begin(), input.end());
  tri->set_lock_data_structure(nullptr);
  return {};
}

// An even permutation of a cell's corners that puts the smallest index first and, of the three
// rotations of the rest, the smallest second: every cell gets one spelling whatever the insertion
// order (an infinite cell, whose -1 is smallest, too). The corners are distinct, so this is the
// lexicographically smallest of the 12 even spellings. kRest[m]: the other three corners in the
// cyclic order that makes (m, kRest[m]...) even.
std::array<int, 4> canonical_order(const std::array<int, 4>& v) {
  static constexpr int kRest[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  int m = 0;
  for (int k = 1; k < 4; ++k)
    if (v[static_cast<std::size_t>(k)] < v[static_cast<std::size_t>(m)]) m = k;
  const int* rest = kRest[m];
  int j = 0;
  for (int k = 1; k < 3; ++k)
    if (v[static_cast<std::size_t>(rest[k])] < v[static_cast<std::size_t>(rest[j])]) j = k;
  return {m, rest[j], rest[(j + 1) % 3], rest[(j + 2) % 3]};
}

// v spelled in the order p: (v[p[0]], v[p[1]], v[p[2]], v[p[3]]).
std::array<int, 4> spelled(const std::array<int, 4>& v, const std::array<int, 4>& p) {
  return {v[static_cast<std::size_t>(p[0])], v[static_cast<std::size_t>(p[1])],
          v[static_cast<std::size_t>(p[2])], v[static_cast<std::size_t>(p[3])]};
}

template <class T>
Result<Triangulation3> extract(T& rt, std::span<const Eigen::Vector3d> points,
                               std::span<const double> weights,
                               const Triangulate3Options& options) {
  constexpr std::string_view kWhat = "triangulate_3d";
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
  //
  // First the cells in the container's order, which is close to their order in memory, so the
  // passes that dereference them read memory in sequence (each cell's info is its index there);
  // the output's order is then made from flat arrays, and the power vertices from the input
  // arrays rather than through the vertices' handles. Measured on the 3.5 million cells of
  // bench_abstraction's fandisk balls: 0.86 -> 0.67 s after the insertion (0.57 s with the balls
  // in spatial order, sampling.cpp).
  //
  // Memory is the other cost: on the virtual machines we run on, every fresh page costs ~16 us
  // (a 1 GiB buffer touched page by page: 4.0-4.2 s), about what the work on it costs. So the
  // corners and neighbours are spelled canonically as they are read, sorted through an index
  // rather than a copy, and moved into their output order in place, which becomes the output:
  // 80 bytes of new memory per cell instead of 132, 64 at the peak instead of 112 (on those 3.5
  // million cells 180 MB less to touch).
  std::vector<typename T::Cell_handle> handles;
  handles.reserve(rt.number_of_cells());
  for (auto c = rt.all_cells_begin(); c != rt.all_cells_end(); ++c) {
    c->info() = static_cast<int>(handles.size());
    handles.push_back(c);
  }
  const std::size_t n = handles.size();
  const bool sort = large(points.size());
  // Corners and neighbours of each cell (container indices), spelled canonically when sorting,
  // else in CGAL's local order.
  std::vector<std::array<int, 4>> corners(n);
  std::vector<std::array<int, 4>> adjacent(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
    for (std::size_t j = range.begin(); j != range.end(); ++j) {
      const typename T::Cell_handle c = handles[j];
      std::array<int, 4> v{}, a{};
      for (int k = 0; k < 4; ++k) {
        const auto h = c->vertex(k);
        v[static_cast<std::size_t>(k)] = rt.is_infinite(h) ? -1 : h->info();
        a[static_cast<std::size_t>(k)] = c->neighbor(k)->info();
      }
      if (sort) {
        const std::array<int, 4> p = canonical_order(v);
        v = spelled(v, p);
        a = spelled(a, p);
      }
      corners[j] = v;
      adjacent[j] = a;
    }
  });
  std::vector<typename T::Cell_handle>().swap(handles);
  if (sort) {
    // order[i]: the container index of output cell i; position is its inverse.
    std::vector<std::uint32_t> order(n);
    // A counting sort on the first corner (the smallest; bucket 0 for -1, the infinite
    // cells), then each bucket sorted by the whole spelling (distinct cells have distinct
    // spellings): a fifth of a comparison sort's time on 3.5 million cells. In parallel: the
    // cells take their places in a bucket by an atomic counter, in whatever order the threads
    // arrive, which the sort of the bucket then undoes.
    const std::size_t buckets = points.size() + 1;
    const auto bucket = [&](std::size_t j) { return static_cast<std::size_t>(corners[j][0] + 1); };
    std::vector<std::atomic<std::uint32_t>> fill(buckets);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
      for (std::size_t j = range.begin(); j != range.end(); ++j)
        fill[bucket(j)].fetch_add(1, std::memory_order_relaxed);
    });
    std::vector<std::uint32_t> start(buckets + 1, 0);  // bucket b: start[b] .. start[b + 1]
    for (std::size_t b = 0; b < buckets; ++b) {
      start[b + 1] = start[b] + fill[b].load(std::memory_order_relaxed);
      fill[b].store(start[b], std::memory_order_relaxed);
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
      for (std::size_t j = range.begin(); j != range.end(); ++j)
        order[fill[bucket(j)].fetch_add(1, std::memory_order_relaxed)] =
            static_cast<std::uint32_t>(j);
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, buckets), [&](const auto& r) {
      for (std::size_t b = r.begin(); b != r.end(); ++b) {
        std::sort(order.begin() + start[b], order.begin() + start[b + 1],
                  [&](std::uint32_t x, std::uint32_t y) { return corners[x] < corners[y]; });
      }
    });
    std::vector<std::uint32_t> position(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i)
        position[order[i]] = static_cast<std::uint32_t>(i);
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
      for (std::size_t j = range.begin(); j != range.end(); ++j)
        for (int& a : adjacent[j]) a = static_cast<int>(position[static_cast<std::size_t>(a)]);
    });
    // Into output order in place, cycle by cycle: slot i takes what was at order[i]. A slot
    // done is marked by order[i] = i.
    for (std::size_t i = 0; i < n; ++i) {
      if (order[i] == i) continue;
      const std::array<int, 4> first_corners = corners[i];
      const std::array<int, 4> first_adjacent = adjacent[i];
      std::size_t to = i;
      for (;;) {
        const std::size_t from = order[to];
        order[to] = static_cast<std::uint32_t>(to);
        if (from == i) {
          corners[to] = first_corners;
          adjacent[to] = first_adjacent;
          break;
        }
        corners[to] = corners[from];
        adjacent[to] = adjacent[from];
        to = from;
      }
    }
  }
  out.cells = std::move(corners);
  out.neighbours = std::move(adjacent);
  out.centres.assign(n, Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  out.squared_radii.assign(n, std::numeric_limits<double>::quiet_NaN());
  const std::span<const std::uint8_t> labels = options.centres_between;
  // Cell by cell, independent: in parallel.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const std::array<int, 4>& v = out.cells[i];
      if (v[0] < 0) continue;  // infinite
      if (!labels.empty()) {
        const std::uint8_t l = labels[static_cast<std::size_t>(v[0])];
        if (labels[static_cast<std::size_t>(v[1])] == l &&
            labels[static_cast<std::size_t>(v[2])] == l &&
            labels[static_cast<std::size_t>(v[3])] == l) {
          continue;
        }
      }
      const auto bpt = [&](int k) {
        const auto q = static_cast<std::size_t>(v[static_cast<std::size_t>(k)]);
        return BPoint(points[q].x(), points[q].y(), points[q].z());
      };
      if constexpr (std::is_same_v<T, Rt>) {
        const auto wpt = [&](int k) {
          const auto q = static_cast<std::size_t>(v[static_cast<std::size_t>(k)]);
          return WPoint(bpt(k), weights.empty() ? 0.0 : weights[q]);
        };
        const auto& traits = rt.geom_traits();
        const WPoint wp = wpt(0), wq = wpt(1), wr = wpt(2), ws = wpt(3);
        const BPoint o = traits.construct_weighted_circumcenter_3_object()(wp, wq, wr, ws);
        out.centres[i] = Eigen::Vector3d(o.x(), o.y(), o.z());
        out.squared_radii[i] = CGAL::to_double(
            traits.compute_squared_radius_smallest_orthogonal_sphere_3_object()(wp, wq, wr, ws));
      } else {
        const BPoint bp = bpt(0), bq = bpt(1), br = bpt(2), bs = bpt(3);
        const BPoint o = CGAL::circumcenter(bp, bq, br, bs);
        out.centres[i] = Eigen::Vector3d(o.x(), o.y(), o.z());
        out.squared_radii[i] = CGAL::squared_distance(o, bp);
      }
    }
  });
  return out;
}

}  // namespace

Result<Triangulation3> triangulate_3d(std::span<const Eigen::Vector3d> points,
                                      std::span<const double> weights,
                                      const Triangulate3Options& options) {
  constexpr std::string_view kWhat = "triangulate_3d";
  return guarded<Triangulation3>(kWhat, [&]() -> Result<Triangulation3> {
    if (!options.centres_between.empty() && options.centres_between.size() != points.size()) {
      return invalid_argument(fmt::format("{}: {} points but {} labels", kWhat, points.size(),
                                          options.centres_between.size()));
    }
    if (weights.empty() && large(points.size())) {
      Dt dt;
      HC_RETURN_IF_ERROR(build(points, weights, kWhat, options.insertion, &dt));
      return extract(dt, points, weights, options);
    }
    Rt rt;
    HC_RETURN_IF_ERROR(build(points, weights, kWhat, options.insertion, &rt));
    return extract(rt, points, weights, options);
  });
}

std::vector<std::size_t> spatial_order(std::span<const Eigen::Vector3d> points) {
  std::vector<std::size_t> order(points.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::vector<BPoint> at;
  at.reserve(points.size());
  for (const auto& p : points) at.emplace_back(p.x(), p.y(), p.z());
  using Map = CGAL::Pointer_property_map<BPoint>::type;
  CGAL::hilbert_sort(order.begin(), order.end(),
                     CGAL::Spatial_sort_traits_adapter_3<K, Map>(CGAL::make_property_map(at)),
                     CGAL::Hilbert_sort_median_policy());
  return order;
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
    HC_RETURN_IF_ERROR(build(centres, weights, kWhat, Insertion::kAuto, &rt));
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
