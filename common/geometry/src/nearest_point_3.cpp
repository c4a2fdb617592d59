// Nearest-point queries by CGAL's k-d tree (sliding midpoint splits, exact distances in double).
#include <CGAL/Orthogonal_k_neighbor_search.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Search_traits_adapter.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/property_map.h>
#include <fmt/format.h>

#include <cmath>
#include <utility>

#include "cgal_support.h"
#include "geometry/nearest_point.h"

namespace hc::geometry {
namespace {

using internal::guarded;
using K = CGAL::Simple_cartesian<double>;
using Point = K::Point_3;
using PointMap = CGAL::Pointer_property_map<Point>::type;
using Traits = CGAL::Search_traits_adapter<std::size_t, PointMap, CGAL::Search_traits_3<K>>;
using Search = CGAL::Orthogonal_k_neighbor_search<Traits>;
using Tree = Search::Tree;

}  // namespace

struct NearestPoint3::Impl {
  std::vector<Point> points;
  std::unique_ptr<Tree> tree;
};

NearestPoint3::NearestPoint3(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NearestPoint3::NearestPoint3(NearestPoint3&&) noexcept = default;
NearestPoint3& NearestPoint3::operator=(NearestPoint3&&) noexcept = default;
NearestPoint3::~NearestPoint3() = default;

Result<NearestPoint3> NearestPoint3::build(std::span<const Eigen::Vector3d> points) {
  constexpr std::string_view kWhat = "nearest_point_3d";
  return guarded<NearestPoint3>(kWhat, [&]() -> Result<NearestPoint3> {
    if (points.empty()) return invalid_argument(fmt::format("{}: no points", kWhat));
    auto impl = std::make_unique<Impl>();
    impl->points.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!points[i].allFinite()) {
        return invalid_argument(fmt::format("{}: point {} is not finite", kWhat, i));
      }
      impl->points.emplace_back(points[i].x(), points[i].y(), points[i].z());
    }
    std::vector<std::size_t> ids(points.size());
    for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = i;
    impl->tree = std::make_unique<Tree>(ids.begin(), ids.end(), Tree::Splitter(),
                                        Traits(PointMap(impl->points.data())));
    impl->tree->build();
    return NearestPoint3(std::move(impl));
  });
}

Result<NearestQuery> NearestPoint3::query(std::span<const Eigen::Vector3d> queries) const {
  constexpr std::string_view kWhat = "nearest_point_3d";
  return guarded<NearestQuery>(kWhat, [&]() -> Result<NearestQuery> {
    NearestQuery out;
    out.distance.resize(queries.size());
    out.index.resize(queries.size());
    const Search::Distance distance(PointMap(impl_->points.data()));
    for (std::size_t i = 0; i < queries.size(); ++i) {
      if (!queries[i].allFinite()) {
        return invalid_argument(fmt::format("{}: query {} is not finite", kWhat, i));
      }
      const Search search(*impl_->tree, Point(queries[i].x(), queries[i].y(), queries[i].z()), 1,
                          0.0, true, distance);
      const auto& nearest = *search.begin();
      out.index[i] = static_cast<int>(nearest.first);
      out.distance[i] = std::sqrt(nearest.second);
    }
    return out;
  });
}

}  // namespace hc::geometry
