// Tetrahedral volume meshes: the shape the FEM, the material fitter and the simulated specimen
// share.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "common/mesh.h"

namespace hc {

using MatrixX4i = Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>;

struct TetMesh {
  MatrixX3d nodes;  // #N by 3 rest positions in metres
  // #T by 4 zero-based node indices, positively oriented: (n1-n0)·((n2-n0)×(n3-n0)) > 0.
  MatrixX4i tets;
  // Optional per-tet region attribute (TetGen's region attribute; e.g. a layer index); empty =
  // none.
  std::vector<int> tet_regions;
  // Optional per-node boundary marker (TetGen's point marker); empty = none.
  std::vector<int> node_markers;
  // Optional per-node attributes (TetGen's point attributes): #N by #A; empty = none.
  Eigen::MatrixXd node_attributes;

  Eigen::Index num_nodes() const { return nodes.rows(); }
  Eigen::Index num_tets() const { return tets.rows(); }
};

// Signed volume of tet t (m³): (n1−n0)·((n2−n0)×(n3−n0)) / 6; positive for a correctly oriented
// tet.
inline double tet_signed_volume(const TetMesh& mesh, Eigen::Index t) {
  const Eigen::Vector3d a = mesh.nodes.row(mesh.tets(t, 0)).transpose();
  const Eigen::Vector3d b = mesh.nodes.row(mesh.tets(t, 1)).transpose();
  const Eigen::Vector3d c = mesh.nodes.row(mesh.tets(t, 2)).transpose();
  const Eigen::Vector3d d = mesh.nodes.row(mesh.tets(t, 3)).transpose();
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

}  // namespace hc
