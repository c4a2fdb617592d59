// Triangle surface meshes: the one in-memory shape every room shares.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>

namespace hc {

// Row-major so that a file's vertex block maps straight onto the matrix storage.
using MatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using MatrixX3i = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct TriangleMesh {
  MatrixX3d vertices;   // #V by 3 positions, in the length unit of the file they came from
  MatrixX3i triangles;  // #F by 3 zero-based vertex indices; counter-clockwise seen from outside

  Eigen::Index num_vertices() const { return vertices.rows(); }
  Eigen::Index num_triangles() const { return triangles.rows(); }
};

// One object of a multi-object print (3MF): its mesh, name and optional material.
struct MeshPart {
  std::string name;
  TriangleMesh mesh;
  std::string material_name;                        // empty: no material assigned
  std::optional<std::array<std::uint8_t, 4>> rgba;  // display colour of the material
};

}  // namespace hc
