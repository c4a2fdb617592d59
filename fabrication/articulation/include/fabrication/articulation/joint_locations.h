// Rigid parts and oriented joint locations from skinning weights (thesis Sec. 6.4.1): each vertex
// belongs to its link of largest weight; edges whose ends belong to different links are
// transition edges, grouped per link pair (Eq. 6.2); each edge gives a transition point
// (Eq. 6.3); PCA of a transition's points gives its centre, and its plane's normal oriented from
// the link nearer the root to the other; transitions whose points do not span a loop
// (lambda3 / lambda2 > f) are degenerate. A joint's centre is where its plane meets an
// approximate medial axis: the deepest point of the mesh's cross-section in that plane around the
// transition centre (the local maximum of the distance to the surface restricted to the plane,
// which lies on the medial axis and always inside), with r_max its distance to the surface.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/status.h"

namespace hc::articulation {

// Each vertex's link: the column of its largest weight (ties: the lower index). #V.
std::vector<int> segment_by_max_weight(const Eigen::MatrixXd& weights);

struct TransitionOptions {
  double degenerate_ratio = 4.0;  // f: thesis Sec. 6.5 used 3.5 to 4.0
  int min_points = 6;             // fewer transition points: degenerate
  Status validate() const;
};

struct Transition {
  int parent_link = -1;  // m: nearer the root (smaller depth; ties: lower index)
  int child_link = -1;   // o
  bool tree_edge = false;  // m is o's parent in the link tree
  std::vector<Eigen::Vector3d> points;  // Eq. 6.3, one per transition edge
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // mean point p
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // n = s e_lambda1, from m towards o
  Eigen::Vector3d major = Eigen::Vector3d::Zero();   // e_lambda3
  Eigen::Vector3d lambdas = Eigen::Vector3d::Zero();  // lambda1 <= lambda2 <= lambda3 (m^2)
  double ratio = 0.0;                                 // lambda3 / lambda2
  bool degenerate = false;
};

// Transitions of a mesh whose vertices carry `weights` (#V by #links, rows summing to 1). A link
// is a column; `link_parent[l]` is the nearest ancestor link (-1 at a root) and `link_depth[l]`
// its depth in the bone tree (root closeness). Sorted by (parent_link, child_link).
Result<std::vector<Transition>> find_transitions(const TriangleMesh& mesh,
                                                 const Eigen::MatrixXd& weights,
                                                 const std::vector<int>& link_parent,
                                                 const std::vector<int>& link_depth,
                                                 const TransitionOptions& options);

struct MedialCentre {
  bool found = false;     // some point of the plane near the transition is inside the mesh
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double r_max = 0.0;     // distance from the centre to the surface
};

// The joint centre of a transition: the deepest point of the plane (centre, normal) within
// search_radius of `centre`, in the inside region connected to the transition centre's nearest
// inside grid point. `depth(x)` is the distance of x to the surface, positive inside.
MedialCentre medial_centre(const Eigen::Vector3d& centre, const Eigen::Vector3d& normal,
                           double search_radius,
                           const std::function<double(const Eigen::Vector3d&)>& depth);

}  // namespace hc::articulation
