// Distance and inside queries against a triangle mesh: CGAL's AABB tree of the triangles and its
// ray-parity inside test (Side_of_triangle_mesh), built once and queried many times.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::geometry {

class MeshDistance {
 public:
  // Builds the tree over the triangles of `mesh` (copied; indices in range, coordinates finite,
  // at least one triangle). inside() needs a closed mesh; distances work on any soup.
  static Result<MeshDistance> build(const TriangleMesh& mesh);

  MeshDistance(MeshDistance&&) noexcept;
  MeshDistance& operator=(MeshDistance&&) noexcept;
  ~MeshDistance();

  // Unsigned distance from p to the nearest point of the surface, in the mesh's unit.
  double distance(const Eigen::Vector3d& p) const;
  // The nearest point of the surface to p, and (optionally) the index of its triangle.
  Eigen::Vector3d closest_point(const Eigen::Vector3d& p, Eigen::Index* triangle = nullptr) const;
  // Whether p lies inside the closed surface (points on it count as inside). Only meaningful
  // when the mesh is closed; is_closed() says whether it is.
  bool inside(const Eigen::Vector3d& p) const;
  // Signed distance: negative inside, positive outside (closed meshes).
  double signed_distance(const Eigen::Vector3d& p) const;
  bool is_closed() const;

 private:
  struct Impl;
  explicit MeshDistance(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::geometry
