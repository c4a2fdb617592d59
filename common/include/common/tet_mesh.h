// Tetrahedral volume meshes: the shape the FEM, the material fitter and the simulated specimen share.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "common/mesh.h"

namespace hc {

using MatrixX4i = Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>;

struct TetMesh {
  MatrixX3d nodes;  // #N by 3 rest positions in metres
  // #T by 4 zero-based node indices, positively oriented: (n1-n0)·((n2-n0)×(n3-n0)) > 0.
  MatrixX4i tets;
  // Optional per-tet region attribute (TetGen's region attribute; e.g. a layer index); empty = none.
  std::vector<int> tet_regions;
  // Optional per-node boundary marker (TetGen's point marker); empty = none.
  std::vector<int> node_markers;

  Eigen::Index num_nodes() const { return nodes.rows(); }
  Eigen::Index num_tets() const { return tets.rows(); }
};

}  // namespace hc
