// Per-element elasticity matrices (CorotationalFem::set_elasticity) for the transversely isotropic
// base materials of thesis Eq. 5.6.
#include <gtest/gtest.h>

#include "processing/fem/corotational.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/verification.h"

namespace hc::fem {
namespace {

TetMesh cube(int cells, double size) {
  return structured_box_mesh(uniform_coordinates(0, size, cells), uniform_coordinates(0, size, cells),
                             uniform_coordinates(0, size, cells));
}

// Eq. 5.6 in Eq. 4.1 order (xy in-plane shear (E11 - E12)/2, xz and yz E44).
Matrix6d transverse(double e11, double e12, double e13, double e33, double e44) {
  Matrix6d e = Matrix6d::Zero();
  e.topLeftCorner<3, 3>() << e11, e12, e13, e12, e11, e13, e13, e13, e33;
  e(3, 3) = 0.5 * (e11 - e12);
  e(4, 4) = e44;
  e(5, 5) = e44;
  return e;
}

// The general path with isotropic matrices equals the (lambda, alpha) path: same K, same solution.
TEST(AnisotropicFem, IsotropicMatricesReproduceLambdaAlpha) {
  const TetMesh mesh = cube(3, 0.01);
  const std::vector<int> fixed = nodes_on_plane(mesh, 2, 0.0, 1e-12);
  auto a = CorotationalFem::create(mesh, fixed);
  auto b = CorotationalFem::create(mesh, fixed);
  ASSERT_TRUE(a.ok() && b.ok());
  const LambdaAlpha p = lambda_alpha_from_youngs_poisson(2e5, 0.35);
  a->set_uniform_params(p);
  ASSERT_TRUE(b->set_elasticity(std::vector<Matrix6d>(mesh.num_tets(), elasticity_matrix(p))).ok());
  MatrixX3d f = MatrixX3d::Zero(mesh.num_nodes(), 3);
  for (int n : nodes_on_plane(mesh, 2, 0.01, 1e-12)) f.row(n) << 0.002, -0.001, -0.03;
  ASSERT_TRUE(a->solve_static(f, 200, 1e-13).ok());
  ASSERT_TRUE(b->solve_static(f, 200, 1e-13).ok());
  const double scale = (a->positions() - mesh.nodes).cwiseAbs().maxCoeff();
  EXPECT_LT((a->positions() - b->positions()).cwiseAbs().maxCoeff(), 1e-10 * scale);
  const SparseMatrix& ka = a->stiffness();
  const SparseMatrix& kb = b->stiffness();
  EXPECT_LT((Eigen::MatrixXd(ka) - Eigen::MatrixXd(kb)).cwiseAbs().maxCoeff(),
            1e-10 * Eigen::MatrixXd(ka).cwiseAbs().maxCoeff());
}

// A uniform strain on a transversely isotropic block: every boundary node prescribed on
// x = (I + eps) X, interior nodes must follow (patch test), and the reactions on the top face must
// add up to sigma_zz A and the tractions' shear parts to sigma_xz A, sigma_yz A with sigma = E eps
// (Hooke's law, Eq. 5.1; expected values computed from E directly).
TEST(AnisotropicFem, UniformStrainGivesHookesStress) {
  constexpr double kSize = 0.01;
  const TetMesh mesh = cube(4, kSize);
  std::vector<int> boundary;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    for (int ax = 0; ax < 3; ++ax)
      if (mesh.nodes(i, ax) < 1e-12 || mesh.nodes(i, ax) > kSize - 1e-12) {
        boundary.push_back(static_cast<int>(i));
        break;
      }
  CorotationalOptions linear;
  linear.corotational = false;
  auto fem = CorotationalFem::create(mesh, boundary, linear);
  ASSERT_TRUE(fem.ok());
  const Matrix6d e = transverse(3e5, 1e5, 0.8e5, 9e5, 0.6e5);
  ASSERT_TRUE(fem->set_elasticity(std::vector<Matrix6d>(mesh.num_tets(), e)).ok());
  Eigen::Matrix3d eps;  // symmetric small strain
  eps << 1e-3, 0.2e-3, -0.3e-3, 0.2e-3, -0.5e-3, 0.4e-3, -0.3e-3, 0.4e-3, 2e-3;
  const MatrixX3d exact = mesh.nodes * (Eigen::Matrix3d::Identity() + eps).transpose();
  MatrixX3d x = mesh.nodes;
  for (int n : boundary) x.row(n) = exact.row(n);
  ASSERT_TRUE(fem->set_positions(x).ok());
  ASSERT_TRUE(fem->solve_static(MatrixX3d::Zero(mesh.num_nodes(), 3), 10, 1e-16).ok());
  EXPECT_LT((fem->positions() - exact).cwiseAbs().maxCoeff(), 1e-9 * kSize);
  Vector6d strain;
  strain << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(0, 1), 2 * eps(0, 2), 2 * eps(1, 2);
  const Vector6d sigma = e * strain;
  // Reactions on the top face z = size: the elastic forces there are minus the reactions.
  Eigen::Vector3d top = Eigen::Vector3d::Zero();
  const MatrixX3d fel = fem->elastic_forces();
  for (int n : nodes_on_plane(mesh, 2, kSize, 1e-12)) top -= fel.row(n).transpose();
  // Edge and corner nodes share the side faces' tractions; the top face's own traction is
  // (sigma_xz, sigma_yz, sigma_zz) A, the sides add half-cells' worth at the rim. Compare with a
  // whole-face balance instead: the sum over the top face minus the rim's side contributions is
  // checked through the bottom face too, so the same rim terms cancel in top - bottom.
  Eigen::Vector3d bottom = Eigen::Vector3d::Zero();
  for (int n : nodes_on_plane(mesh, 2, 0.0, 1e-12)) bottom -= fel.row(n).transpose();
  const double area = kSize * kSize;
  const Eigen::Vector3d expected(sigma(4), sigma(5), sigma(2));  // (xz, yz, zz) on a +z face
  EXPECT_NEAR(0.5 * (top - bottom).z(), expected.z() * area, 1e-9 * std::abs(expected.z() * area));
  EXPECT_NEAR(0.5 * (top - bottom).x(), expected.x() * area, 1e-9 * sigma.cwiseAbs().maxCoeff() * area);
  EXPECT_NEAR(0.5 * (top - bottom).y(), expected.y() * area, 1e-9 * sigma.cwiseAbs().maxCoeff() * area);
}

// A non-symmetric or non-finite matrix is refused, naming the element.
TEST(AnisotropicFem, RejectsBadMatrices) {
  const TetMesh mesh = cube(1, 0.01);
  auto fem = CorotationalFem::create(mesh, {0, 1, 2, 3});
  ASSERT_TRUE(fem.ok());
  std::vector<Matrix6d> e(mesh.num_tets(), transverse(3, 1, 1, 9, 1));
  e[2](0, 1) += 1;
  const Status s = fem->set_elasticity(e);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("element 2"), std::string::npos) << s.message();
  e[2] = Matrix6d::Constant(std::nan(""));
  EXPECT_FALSE(fem->set_elasticity(e).ok());
  EXPECT_FALSE(fem->set_elasticity(std::vector<Matrix6d>(2, transverse(3, 1, 1, 9, 1))).ok());
}

}  // namespace
}  // namespace hc::fem
