// Proximity between two triangle meshes: the closest approach of their surfaces and the pairs of
// triangles that cross, from an AABB tree over one mesh queried with the other's triangles
// (CGAL's AABB_tree and exact Triangle_3 intersection predicates). What joint collision tests,
// clearance checks and motion sweeps ask of two parts.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::geometry {

struct ClosestApproach {
  bool found = false;  // some pair of triangles is within the search radius
  double distance = 0.0;  // 0 when the surfaces cross
  Eigen::Vector3d point_a = Eigen::Vector3d::Zero();  // on the query mesh
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();  // on the tree's mesh
  Eigen::Index triangle_a = -1;
  Eigen::Index triangle_b = -1;
};

struct CrossingPair {
  Eigen::Index triangle_a = -1;  // query mesh
  Eigen::Index triangle_b = -1;  // tree's mesh
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // on both triangles (their intersection's middle)
};

// A tree over one mesh ("b"), queried with others ("a"). Indices must be in range and
// coordinates finite (checked by build, kInvalidArgument).
class MeshProximity {
 public:
  static Result<MeshProximity> build(const TriangleMesh& b);

  MeshProximity(MeshProximity&&) noexcept;
  MeshProximity& operator=(MeshProximity&&) noexcept;
  ~MeshProximity();

  // The closest pair of points of the two surfaces among triangle pairs within `radius` (> 0) of
  // each other; found = false when no pair is that close. Exact for triangles (each pair's
  // distance is the least of its vertex-triangle and edge-edge distances, crossing tested by
  // CGAL's exact predicate).
  Result<ClosestApproach> closest_approach(const TriangleMesh& a, double radius) const;

  // Pairs of triangles whose surfaces cross (exact predicate; pairs merely touching count too),
  // at most max_pairs (0: all).
  Result<std::vector<CrossingPair>> crossings(const TriangleMesh& a,
                                              std::size_t max_pairs = 0) const;

  // Whether the point lies inside the tree's mesh (ray parity, majority of three rays; the mesh
  // must be closed).
  bool contains(const Eigen::Vector3d& p) const;

  // The tree's mesh and the solid of a closed `a` overlap: their surfaces cross, or one holds the
  // other (a vertex of either inside the other).
  Result<bool> solids_overlap(const TriangleMesh& a) const;

 private:
  struct Impl;
  explicit MeshProximity(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Closest points of two triangles (a0 a1 a2) and (b0 b1 b2) that do not cross: the least of the
// six vertex-to-triangle and nine edge-to-edge distances. Returns the distance.
double triangle_closest_points(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                               const Eigen::Vector3d& a2, const Eigen::Vector3d& b0,
                               const Eigen::Vector3d& b1, const Eigen::Vector3d& b2,
                               Eigen::Vector3d* pa, Eigen::Vector3d* pb);

}  // namespace hc::geometry
