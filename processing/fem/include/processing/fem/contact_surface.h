// Where a rigid probe meets a tet mesh: the contact points of its boundary (thesis Sec. 4.2.4's
// probe contact, made independent of the mesh resolution).
//
// Contact evaluated at the nodes alone lets a probe smaller than the elements sit between them: on
// a coarse block a sphere meets no node, the force stays zero and the probe "does not reach" the
// specimen. Here the penetration is integrated over the boundary: every boundary triangle the
// probe's path can reach is split into m × m sub-triangles (m = ceil(longest edge / spacing)) and
// their corners are contact points, weighted by the composite trapezoidal rule (corner A/(3m²),
// edge A/m², interior 2A/m²; exact area). Points on a triangle move with it (x = Σ w_k x_k over its
// three nodes), so their penalty forces reach the nodes by the same weights. On a mesh finer than
// the spacing m = 1 everywhere and the points are exactly the boundary nodes (the thesis's node
// contact), each weighted by a third of its triangles' areas. Only triangles longer than the
// probe's feature size are split (see ContactSamplingOptions).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/fem/probe.h"

namespace hc::fem {

class CorotationalFem;

// One boundary triangle of a tet mesh: its nodes counter-clockwise seen from outside, the tet it
// belongs to and the nodes' local indices (0..3) in that tet.
struct BoundaryFace {
  std::array<int, 3> nodes{};
  int tet = -1;
  std::array<int, 3> local{};
};

// The faces used by exactly one tet, oriented outward. Sorted by (tet, local face).
std::vector<BoundaryFace> boundary_faces(const TetMesh& mesh);

// A point of a triangle surface: x = Σ_k weights(k) x_{nodes[k]}. `area_m2` is its quadrature
// weight (the share of the surface it stands for).
struct ContactPoint {
  std::array<int, 3> nodes{};
  Eigen::Vector3d weights = Eigen::Vector3d(1, 0, 0);
  double area_m2 = 0;
  int face = -1;  // triangle (surface sampling) or BoundaryFace (ContactSurface) it lies on
  // A node's own point (weights (1, 0, 0)): the node is nodes[0].
  bool is_node() const { return weights(1) == 0 && weights(2) == 0; }
};

struct ContactSamplingOptions {
  // Triangles whose longest edge exceeds this (m) are split when the probe can reach them; 0: the
  // probe's feature size (half its smallest bounding-box extent: a sphere's or a punch's radius).
  // Finer meshes keep the thesis's node contact, which converges to the closed forms: points on a
  // linear triangle hold the whole triangle, so splitting a triangle under a punch's rim stiffens
  // the contact (measured +25 % at 2 elements per punch radius), and many points along the rim's
  // edge make the active set cycle. A sphere of radius R sinks at most 0.18 R between the nodes of
  // a triangle shorter than R before a node meets it.
  double split_above_m = 0;
  // Largest distance between neighbouring contact points on split triangles (m); 0: an eighth of
  // the probe's feature size, so that a sphere sinks at most R/256 between points before one of
  // them touches it.
  double spacing_m = 0;
  // Triangles whose bounding sphere is farther than this from the probe's axis (the line through
  // its reference point along its direction) keep their nodes only; 0: 1.5 × the probe's lateral
  // extent (largest distance of its bounding box from the axis).
  double reach_m = 0;
  long max_points = 4000000;  // guard against a spacing far below the mesh size (error beyond)

  Status validate() const;
};

// Samples the triangle surface (vertices #V by 3, triangles #F by 3) for contact with `probe` at
// its pose, moving along its direction: one point per vertex used by a triangle (area = its share
// of the lattice weights of its triangles) and, on the reachable triangles longer than
// split_above_m, the edge and interior lattice points within reach_m of the probe's axis. A
// triangle is reachable when it comes within reach_m of the axis and does not face away from the
// probe's travel (triangles are oriented outward; a probe cannot touch a face whose outward normal
// points along its direction, such as a fixed base under it, before passing through the body).
// invalid_argument for bad indices or options; resource_exhausted-style invalid_argument when more
// than max_points would be made.
Result<std::vector<ContactPoint>> sample_contact_points(const MatrixX3d& vertices,
                                                        const MatrixX3i& triangles,
                                                        const Probe& probe,
                                                        const ContactSamplingOptions& options = {});

// The error for a probe whose path misses the specimen (bounds in metres): where the probe is, where
// it moves, where the specimen is, and the fix.
Status probe_misses_specimen(const Probe& probe, const Eigen::AlignedBox3d& specimen,
                             double max_travel_m);

// The contact points of a tet mesh's boundary for one probe, with each point's tet for assembly.
class ContactSurface {
 public:
  static Result<ContactSurface> create(const TetMesh& mesh, const Probe& probe,
                                       const ContactSamplingOptions& options = {});

  const std::vector<ContactPoint>& points() const { return points_; }
  const std::vector<BoundaryFace>& faces() const { return faces_; }
  // The tet holding point i's nodes and their local indices in it.
  int tet(std::size_t i) const { return faces_[static_cast<std::size_t>(points_[i].face)].tet; }
  std::array<int, 3> local(std::size_t i) const;
  // Position of point i for node positions x (#N by 3).
  Eigen::Vector3d position(const MatrixX3d& x, std::size_t i) const;
  // Positions of all points, #P by 3 (row-major, as Probe::travel_to_contact takes them).
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> positions(const MatrixX3d& x) const;
  // Boundary area per node (m²): the sum of its points' shares; 0 for interior nodes.
  const Eigen::VectorXd& node_area() const { return node_area_; }

  // Travel (m) of `probe` along its direction from its pose to the first contact with a point that
  // can move (a node with non-zero weight not fixed; `fixed` has one flag per node) at node
  // positions `x`. invalid_argument naming the probe, its direction and the specimen's bounds when
  // no such point is reached within max_travel_m.
  Result<double> travel_to_contact(const Probe& probe, const MatrixX3d& x,
                                   const std::vector<char>& fixed, double max_travel_m) const;

  // Penalty stiffness of every point (N/m), proportional to its area: k_p = s · area_p ·
  // Σ_k w_k d_k / A_k over the point's free nodes k, with A_k the node's boundary area and d_k the
  // mean diagonal entry of `fem`'s assembled stiffness at node k (N/m), s = penalty_scale; with
  // penalty_n_per_m > 0, d_k = penalty_n_per_m / penalty_scale instead. A node's own point on a
  // fine mesh therefore gets s times its diagonal (the node contact's rule). Points whose nodes are
  // all fixed get 0.
  std::vector<double> penalty_stiffness(const CorotationalFem& fem, double penalty_scale,
                                        double penalty_n_per_m = 0) const;

 private:
  std::vector<BoundaryFace> faces_;
  std::vector<ContactPoint> points_;
  Eigen::VectorXd node_area_;
};

}  // namespace hc::fem
