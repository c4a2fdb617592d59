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
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <unordered_map>
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
// Hidden points are not kept: the medial-ball code only needs which points became vertices.
using Cb = CGAL::Regular_triangulation_cell_base_3<Gt, CGAL::Triangulation_cell_base_3<Gt>,
                                                   CGAL::Discard_hidden_points>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
using Rt = CGAL::Regular_triangulation_3<Gt, Tds>;
using WPoint = Gt::Weighted_point_3;
using BPoint = Gt::Point_3;

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

Result<Rt> build(std::span<const Eigen::Vector3d> points, std::span<const double> weights,
                 std::string_view what) {
  HC_RETURN_IF_ERROR(check_input(points, weights, what));
  std::vector<std::pair<WPoint, int>> input;
  input.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights.empty() ? 0.0 : weights[i];
    input.emplace_back(WPoint(BPoint(points[i].x(), points[i].y(), points[i].z()), w),
                       static_cast<int>(i));
  }
  // The range insertion sorts the points along a Hilbert curve first (spatial_sort).
  Rt rt(input.begin(), input.end());
  return rt;
}

}  // namespace

Result<Triangulation3> triangulate_3d(std::span<const Eigen::Vector3d> points,
                                      std::span<const double> weights) {
  constexpr std::string_view kWhat = "triangulate_3d";
  return guarded<Triangulation3>(kWhat, [&]() -> Result<Triangulation3> {
    HC_ASSIGN_OR_RETURN(Rt rt, build(points, weights, kWhat));
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
    std::unordered_map<Rt::Cell_handle, int> index;
    index.reserve(rt.number_of_cells());
    int n = 0;
    for (auto c = rt.all_cells_begin(); c != rt.all_cells_end(); ++c) index.emplace(c, n++);
    out.cells.resize(static_cast<std::size_t>(n));
    out.neighbours.resize(static_cast<std::size_t>(n));
    out.centres.assign(static_cast<std::size_t>(n),
                       Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    out.squared_radii.assign(static_cast<std::size_t>(n), std::numeric_limits<double>::quiet_NaN());
    const auto centre = rt.geom_traits().construct_weighted_circumcenter_3_object();
    const auto radius =
        rt.geom_traits().compute_squared_radius_smallest_orthogonal_sphere_3_object();
    for (auto c = rt.all_cells_begin(); c != rt.all_cells_end(); ++c) {
      const auto i = static_cast<std::size_t>(index.at(c));
      for (int k = 0; k < 4; ++k) {
        const auto v = c->vertex(k);
        out.cells[i][static_cast<std::size_t>(k)] = rt.is_infinite(v) ? -1 : v->info();
        out.neighbours[i][static_cast<std::size_t>(k)] = index.at(c->neighbor(k));
      }
      if (rt.is_infinite(c)) continue;
      const WPoint& p = c->vertex(0)->point();
      const WPoint& q = c->vertex(1)->point();
      const WPoint& r = c->vertex(2)->point();
      const WPoint& s = c->vertex(3)->point();
      const BPoint o = centre(p, q, r, s);
      out.centres[i] = Eigen::Vector3d(o.x(), o.y(), o.z());
      out.squared_radii[i] = CGAL::to_double(radius(p, q, r, s));
    }
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
    HC_ASSIGN_OR_RETURN(Rt rt, build(centres, weights, kWhat));
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
