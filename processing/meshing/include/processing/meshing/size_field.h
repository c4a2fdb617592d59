// Mesh sizing functions for TetGen (its '-m' switch): TetGen reads the desired edge length at the
// nodes of a background tet mesh and interpolates it linearly inside its tets. background_mesh()
// builds one for any size function: an octree over the domain's bounding box, refined until each
// cell is at most twice the size at its centre (so that linear interpolation between its corners
// follows the function), whose corners are tetrahedralised (Delaunay).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "common/tet_mesh.h"

namespace hc::meshing {

// Desired edge length (input units, > 0) at a point.
using EdgeSizeFunction = std::function<double(const Eigen::Vector3d&)>;

// The background mesh: nodes and Delaunay tets covering `box` (slightly enlarged), with the size at
// every node (node_attributes column 0). invalid_argument when `size` returns a non-finite or
// non-positive value, or the octree would exceed max_cells (a size far below the box).
Result<TetMesh> background_mesh(const EdgeSizeFunction& size, const Eigen::AlignedBox3d& box,
                                long max_cells = 2000000);

// The number of tets TetGen makes in `box` (filled) with this sizing, estimated from the measured
// mean tet volume 0.21 size³ (TetGen 1.5, quality bound 1.414, uniform sizes on a box).
double estimate_tet_count(const EdgeSizeFunction& size, const Eigen::AlignedBox3d& box);

// A size field graded away from a focus: `fine` within `radius` of `centre`, growing by
// `growth` per unit distance beyond it, at most `coarse`.
struct GradedSize {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0;
  double fine = 0;
  double growth = 0.3;
  double coarse = 0;
  double operator()(const Eigen::Vector3d& p) const;
};

}  // namespace hc::meshing
