// CGAL's AABB tree and Side_of_triangle_mesh behind geometry/mesh_distance.h.
#include "geometry/mesh_distance.h"

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <vector>

#include "cgal_support.h"

namespace hc::geometry {
namespace {
namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
using Inside = CGAL::Side_of_triangle_mesh<SurfaceMesh, Kernel>;
}  // namespace

struct MeshDistance::Impl {
  SurfaceMesh mesh;
  std::vector<Eigen::Index> triangle_of_face;  // face index -> row of the input's triangles
  Tree tree;
  std::unique_ptr<Inside> inside;
  bool closed = false;
};

MeshDistance::MeshDistance(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MeshDistance::MeshDistance(MeshDistance&&) noexcept = default;
MeshDistance& MeshDistance::operator=(MeshDistance&&) noexcept = default;
MeshDistance::~MeshDistance() = default;

Result<MeshDistance> MeshDistance::build(const TriangleMesh& mesh) {
  if (mesh.num_triangles() == 0) return invalid_argument("mesh distance: the mesh has no triangles");
  return internal::guarded<MeshDistance>("mesh distance", [&]() -> Result<MeshDistance> {
    auto impl = std::make_unique<Impl>();
    // A soup is made a Surface_mesh through CGAL's orientation pass, which duplicates vertices at
    // non-manifold spots; each face keeps the row of the triangle it came from.
    std::vector<Point> points;
    for (Eigen::Index v = 0; v < mesh.num_vertices(); ++v) {
      if (!mesh.vertices.row(v).allFinite()) {
        return invalid_argument(fmt::format("mesh distance: vertex {} is not finite", v));
      }
      points.emplace_back(mesh.vertices(v, 0), mesh.vertices(v, 1), mesh.vertices(v, 2));
    }
    std::vector<std::array<std::size_t, 3>> faces;
    for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
      std::array<std::size_t, 3> f{};
      for (int k = 0; k < 3; ++k) {
        const int idx = mesh.triangles(t, k);
        if (idx < 0 || idx >= mesh.num_vertices()) {
          return invalid_argument(
              fmt::format("mesh distance: triangle {} has vertex index {} out of range", t, idx));
        }
        f[static_cast<std::size_t>(k)] = static_cast<std::size_t>(idx);
      }
      if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) continue;  // no area, no distance
      faces.push_back(f);
      impl->triangle_of_face.push_back(t);
    }
    PMP::orient_polygon_soup(points, faces);
    PMP::polygon_soup_to_polygon_mesh(points, faces, impl->mesh);
    // orient_polygon_soup keeps the faces in order (it may reverse some), so face f of the
    // Surface_mesh is faces[f], whose row triangle_of_face keeps.
    if (impl->mesh.number_of_faces() == 0) {
      return invalid_argument("mesh distance: no triangle with three distinct corners");
    }
    impl->tree.insert(CGAL::faces(impl->mesh).first, CGAL::faces(impl->mesh).second, impl->mesh);
    impl->tree.accelerate_distance_queries();
    impl->closed = CGAL::is_closed(impl->mesh);
    impl->inside = std::make_unique<Inside>(impl->mesh);
    return MeshDistance(std::move(impl));
  });
}

double MeshDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(CGAL::to_double(impl_->tree.squared_distance(Point(p.x(), p.y(), p.z()))));
}

Eigen::Vector3d MeshDistance::closest_point(const Eigen::Vector3d& p, Eigen::Index* triangle) const {
  const auto [q, face] = impl_->tree.closest_point_and_primitive(Point(p.x(), p.y(), p.z()));
  if (triangle != nullptr) *triangle = impl_->triangle_of_face[face.idx()];
  return {q.x(), q.y(), q.z()};
}

bool MeshDistance::inside(const Eigen::Vector3d& p) const {
  return (*impl_->inside)(Point(p.x(), p.y(), p.z())) != CGAL::ON_UNBOUNDED_SIDE;
}

double MeshDistance::signed_distance(const Eigen::Vector3d& p) const {
  const double d = distance(p);
  return inside(p) ? -d : d;
}

bool MeshDistance::is_closed() const { return impl_->closed; }

}  // namespace hc::geometry
