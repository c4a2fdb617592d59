// Regular (and Delaunay) triangulations in the plane: CGAL's Regular_triangulation_2 on the Epick
// kernel (exact predicates); orthocentres re-constructed on Epeck and rounded once, so that the
// power diagram's vertices are correctly rounded (2-D inputs are small: thousands of points).
#include <CGAL/Cartesian_converter.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_2.h>
#include <CGAL/Regular_triangulation_face_base_2.h>
#include <CGAL/Regular_triangulation_vertex_base_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <unordered_map>
#include <utility>

#include "cgal_support.h"
#include "geometry/triangulation_2d.h"

namespace hc::geometry {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using EK = CGAL::Exact_predicates_exact_constructions_kernel;
using Vb0 = CGAL::Regular_triangulation_vertex_base_2<K>;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K, Vb0>;
using Fb = CGAL::Regular_triangulation_face_base_2<K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Rt = CGAL::Regular_triangulation_2<K, Tds>;
using WPoint = K::Weighted_point_2;
using BPoint = K::Point_2;

using internal::guarded;

Result<Rt> build(std::span<const Eigen::Vector2d> points, std::span<const double> weights,
                 std::string_view what) {
  if (!weights.empty() && weights.size() != points.size()) {
    return invalid_argument(
        fmt::format("{}: {} points but {} weights", what, points.size(), weights.size()));
  }
  std::vector<std::pair<WPoint, int>> input;
  input.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights.empty() ? 0.0 : weights[i];
    if (!points[i].allFinite() || !std::isfinite(w)) {
      return invalid_argument(fmt::format("{}: point {} is not finite", what, i));
    }
    input.emplace_back(WPoint(BPoint(points[i].x(), points[i].y()), w), static_cast<int>(i));
  }
  Rt rt;
  rt.insert(input.begin(), input.end());
  return rt;
}

}  // namespace

Result<Triangulation2> triangulate_2d(std::span<const Eigen::Vector2d> points,
                                      std::span<const double> weights) {
  constexpr std::string_view kWhat = "triangulate_2d";
  return guarded<Triangulation2>(kWhat, [&]() -> Result<Triangulation2> {
    HC_ASSIGN_OR_RETURN(Rt rt, build(points, weights, kWhat));
    if (rt.dimension() < 2) {
      return invalid_argument(fmt::format("{}: the {} points are collinear; 2 dimensions needed",
                                          kWhat, points.size()));
    }
    Triangulation2 out;
    out.is_vertex.assign(points.size(), 0);
    for (auto v = rt.finite_vertices_begin(); v != rt.finite_vertices_end(); ++v) {
      out.is_vertex[static_cast<std::size_t>(v->info())] = 1;
    }
    std::unordered_map<Rt::Face_handle, int> index;
    int n = 0;
    for (auto f = rt.all_faces_begin(); f != rt.all_faces_end(); ++f) index.emplace(f, n++);
    out.triangles.resize(static_cast<std::size_t>(n));
    out.neighbours.resize(static_cast<std::size_t>(n));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    out.centres.assign(static_cast<std::size_t>(n), Eigen::Vector2d(nan, nan));
    out.squared_radii.assign(static_cast<std::size_t>(n), nan);
    const CGAL::Cartesian_converter<K, EK> to_exact;
    const auto centre = EK().construct_weighted_circumcenter_2_object();
    for (auto f = rt.all_faces_begin(); f != rt.all_faces_end(); ++f) {
      const auto i = static_cast<std::size_t>(index.at(f));
      for (int k = 0; k < 3; ++k) {
        const auto v = f->vertex(k);
        out.triangles[i][static_cast<std::size_t>(k)] = rt.is_infinite(v) ? -1 : v->info();
        out.neighbours[i][static_cast<std::size_t>(k)] = index.at(f->neighbor(k));
      }
      if (rt.is_infinite(f)) continue;
      const EK::Weighted_point_2 p = to_exact(f->vertex(0)->point());
      const EK::Weighted_point_2 q = to_exact(f->vertex(1)->point());
      const EK::Weighted_point_2 r = to_exact(f->vertex(2)->point());
      const EK::Point_2 o = centre(p, q, r);
      const double x = CGAL::to_double(CGAL::exact(o.x()));
      const double y = CGAL::to_double(CGAL::exact(o.y()));
      out.centres[i] = Eigen::Vector2d(x, y);
      // Power of the centre with respect to corner 0 = squared radius of the orthogonal circle.
      const Eigen::Vector2d c0(f->vertex(0)->point().x(), f->vertex(0)->point().y());
      out.squared_radii[i] = (out.centres[i] - c0).squaredNorm() - f->vertex(0)->point().weight();
    }
    return out;
  });
}

Result<PowerQuery2> nearest_power_2d(std::span<const Eigen::Vector2d> centres,
                                     std::span<const double> weights,
                                     std::span<const Eigen::Vector2d> queries) {
  constexpr std::string_view kWhat = "nearest_power_2d";
  return guarded<PowerQuery2>(kWhat, [&]() -> Result<PowerQuery2> {
    if (centres.empty() || weights.size() != centres.size()) {
      return invalid_argument(
          fmt::format("{}: {} balls with {} weights", kWhat, centres.size(), weights.size()));
    }
    HC_ASSIGN_OR_RETURN(Rt rt, build(centres, weights, kWhat));
    PowerQuery2 out;
    out.power.resize(queries.size());
    out.ball.resize(queries.size());
    for (std::size_t i = 0; i < queries.size(); ++i) {
      if (!queries[i].allFinite()) {
        return invalid_argument(fmt::format("{}: query {} is not finite", kWhat, i));
      }
      const auto v = rt.nearest_power_vertex(BPoint(queries[i].x(), queries[i].y()));
      const int b = v->info();
      out.ball[i] = b;
      out.power[i] = (queries[i] - centres[static_cast<std::size_t>(b)]).squaredNorm() -
                     weights[static_cast<std::size_t>(b)];
    }
    return out;
  });
}

}  // namespace hc::geometry
