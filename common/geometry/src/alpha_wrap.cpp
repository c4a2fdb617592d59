// CGAL::alpha_wrap_3 behind geometry/alpha_wrap.h.
#include "geometry/alpha_wrap.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/alpha_wrap_3.h>

#include <array>
#include <cmath>
#include <vector>

#include "cgal_support.h"

namespace hc::geometry {
namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
}  // namespace

Status AlphaWrapOptions::validate() const {
  if (!(alpha > 0.0) || !std::isfinite(alpha)) {
    return invalid_argument(fmt::format("alpha wrap: alpha must be > 0, got {}", alpha));
  }
  if (!(offset > 0.0) || !std::isfinite(offset)) {
    return invalid_argument(fmt::format("alpha wrap: offset must be > 0, got {}", offset));
  }
  return Status();
}

Result<TriangleMesh> alpha_wrap(const TriangleMesh& soup, const AlphaWrapOptions& options) {
  if (Status s = options.validate(); !s.ok()) return s;
  if (soup.num_triangles() == 0) return invalid_argument("alpha wrap: the input has no triangles");
  std::vector<Point> points;
  points.reserve(static_cast<std::size_t>(soup.num_vertices()));
  for (Eigen::Index v = 0; v < soup.num_vertices(); ++v) {
    const auto row = soup.vertices.row(v);
    if (!row.allFinite()) {
      return invalid_argument(fmt::format("alpha wrap: vertex {} is not finite", v));
    }
    points.emplace_back(row(0), row(1), row(2));
  }
  std::vector<std::array<std::size_t, 3>> faces;
  faces.reserve(static_cast<std::size_t>(soup.num_triangles()));
  for (Eigen::Index t = 0; t < soup.num_triangles(); ++t) {
    std::array<std::size_t, 3> f{};
    for (int k = 0; k < 3; ++k) {
      const int idx = soup.triangles(t, k);
      if (idx < 0 || idx >= soup.num_vertices()) {
        return invalid_argument(
            fmt::format("alpha wrap: triangle {} has vertex index {} out of range", t, idx));
      }
      f[static_cast<std::size_t>(k)] = static_cast<std::size_t>(idx);
    }
    faces.push_back(f);
  }
  return internal::guarded<TriangleMesh>("alpha wrap", [&]() -> Result<TriangleMesh> {
    CGAL::Surface_mesh<Point> wrap;
    CGAL::alpha_wrap_3(points, faces, options.alpha, options.offset, wrap);
    if (wrap.number_of_faces() == 0) return internal_error("alpha wrap: CGAL returned no surface");
    return internal::to_triangle_mesh(wrap);
  });
}

}  // namespace hc::geometry
