// Internal to hardcopy_geometry (included only by common/geometry/src/*.cpp): conversions between
// hc::TriangleMesh and CGAL's Surface_mesh for any kernel, and the guard that turns whatever CGAL
// throws into a Status so that no exception leaves the geometry target.
#pragma once

#include <CGAL/Surface_mesh.h>
#include <fmt/format.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <exception>
#include <string_view>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::geometry::internal {

// Runs `body` (returning Result<T>), turning an exception into kInternal naming `what`.
template <class T, class Body>
Result<T> guarded(std::string_view what, Body&& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    return internal_error(fmt::format("{}: CGAL failed: {}", what, e.what()));
  } catch (...) {
    return internal_error(fmt::format("{}: CGAL failed with an unknown exception", what));
  }
}

// `mesh` as a Surface_mesh; fails when a triangle does not fit a manifold, consistently oriented
// surface (CGAL's add_face refuses it) or an index is out of range.
template <class Point>
Result<CGAL::Surface_mesh<Point>> to_surface_mesh(const TriangleMesh& mesh, std::string_view what) {
  using SurfaceMesh = CGAL::Surface_mesh<Point>;
  SurfaceMesh sm;
  sm.reserve(static_cast<typename SurfaceMesh::size_type>(mesh.num_vertices()),
             static_cast<typename SurfaceMesh::size_type>(3 * mesh.num_triangles() / 2),
             static_cast<typename SurfaceMesh::size_type>(mesh.num_triangles()));
  std::vector<typename SurfaceMesh::Vertex_index> v(static_cast<std::size_t>(mesh.num_vertices()));
  for (Eigen::Index i = 0; i < mesh.num_vertices(); ++i) {
    if (!std::isfinite(mesh.vertices(i, 0)) || !std::isfinite(mesh.vertices(i, 1)) ||
        !std::isfinite(mesh.vertices(i, 2))) {
      return invalid_argument(fmt::format("{}: vertex {} is not finite", what, i));
    }
    v[static_cast<std::size_t>(i)] =
        sm.add_vertex(Point(mesh.vertices(i, 0), mesh.vertices(i, 1), mesh.vertices(i, 2)));
  }
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    std::array<typename SurfaceMesh::Vertex_index, 3> c;
    for (int k = 0; k < 3; ++k) {
      const int idx = mesh.triangles(t, k);
      if (idx < 0 || idx >= mesh.num_vertices()) {
        return invalid_argument(fmt::format("{}: triangle {} has vertex index {} out of range", what,
                                            t, idx));
      }
      c[static_cast<std::size_t>(k)] = v[static_cast<std::size_t>(idx)];
    }
    if (sm.add_face(c[0], c[1], c[2]) == SurfaceMesh::null_face()) {
      return invalid_argument(fmt::format(
          "{}: triangle {} does not fit a manifold, consistently oriented surface", what, t));
    }
  }
  return sm;
}

// The faces of `sm` (triangles) as a TriangleMesh with coordinates rounded to double; vertices
// without a face are dropped.
template <class Point>
TriangleMesh to_triangle_mesh(const CGAL::Surface_mesh<Point>& sm) {
  TriangleMesh out;
  std::vector<Eigen::Index> index(sm.number_of_vertices() + sm.number_of_removed_vertices(), -1);
  Eigen::Index nv = 0;
  for (auto v : sm.vertices()) {
    if (!sm.is_isolated(v)) index[v.idx()] = nv++;
  }
  out.vertices.resize(nv, 3);
  for (auto v : sm.vertices()) {
    if (index[v.idx()] < 0) continue;
    const auto& p = sm.point(v);
    out.vertices.row(index[v.idx()]) << CGAL::to_double(p.x()), CGAL::to_double(p.y()),
        CGAL::to_double(p.z());
  }
  out.triangles.resize(static_cast<Eigen::Index>(sm.number_of_faces()), 3);
  Eigen::Index t = 0;
  for (auto f : sm.faces()) {
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      if (k < 3) out.triangles(t, k) = static_cast<int>(index[v.idx()]);
      ++k;
    }
    ++t;
  }
  return out;
}

}  // namespace hc::geometry::internal
