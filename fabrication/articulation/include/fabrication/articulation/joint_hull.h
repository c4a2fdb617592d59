// Joint hulls (thesis Sec. 6.4.3): the volume carved out of the fabrication mesh to make a joint,
// polygonised from the joint's parametric design (joint_design.h) as a CSG of faceted solids
// (primitives.h) evaluated exactly (geometry/csg_sequence.h), with friction bumps left on the
// moving part and dimples of radius r_b + d around them in the other.
//
// The cut surfaces reach out of the character: along every direction the hull's outer cap is
// placed just past where a ray from the joint leaves the fabrication mesh (sphere tracing the
// mesh's distance function), so a hull cuts its own limb through and nothing beyond it.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"
#include "fabrication/articulation/joint.h"

namespace hc::articulation {

struct HullOptions {
  double clearance_m = 0.3e-3;
  double bump_radius_m = 0.7e-3;  // 0: no friction bumps
  int segments = 48;              // facets around a full turn
  double reach_margin_m = 1e-3;   // how far past the mesh's surface the cut surfaces go
};

struct JointHull {
  TriangleMesh hull;  // closed, outward; world frame (m)
  std::vector<Eigen::Vector3d> bumps;  // centres of the friction bumps (world)
  double bump_radius_m = 0.0;
  double reach_m = 0.0;  // farthest point of the hull from the centre
};

// Distance from a ray's origin (inside the mesh) to where it leaves the mesh, by sphere tracing
// `depth` (distance to the surface, positive inside). 0 when the origin is outside.
double exit_distance(const std::function<double(const Eigen::Vector3d&)>& depth,
                     const Eigen::Vector3d& origin, const Eigen::Vector3d& direction);

// Builds the hull of a feasible joint (its design filled for its type). `depth` is the
// fabrication mesh's inside distance.
Result<JointHull> build_joint_hull(const Joint& joint, const HullOptions& options,
                                   const std::function<double(const Eigen::Vector3d&)>& depth);

}  // namespace hc::articulation
