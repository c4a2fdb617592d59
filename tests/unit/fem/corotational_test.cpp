// Co-rotational FEM: Eqs. 4.3-4.8, the fast warped assembly against B^T E B, rigid-motion
// invariance, patch test, bad meshes.
#include "processing/fem/corotational.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "processing/fem/material_model.h"
#include "processing/fem/verification.h"

namespace hc::fem {
namespace {

TetMesh small_box() {
  return structured_box_mesh(uniform_coordinates(0, 0.02, 2), uniform_coordinates(0, 0.01, 2),
                             uniform_coordinates(0, 0.01, 1));
}

Eigen::Matrix3d random_rotation(double angle, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

TEST(Elasticity, LambdaAlphaFormEqualsYoungsPoissonFormAndHooke) {
  const double e = 2.5e6, nu = 0.37;
  const LambdaAlpha p = lambda_alpha_from_youngs_poisson(e, nu);
  // Eq. 4.3 vs Eq. 4.6.
  const Matrix6d eq43 = e / ((1 + nu) * (1 - 2 * nu)) * (g_matrix() + nu * h_matrix());
  EXPECT_LT((elasticity_matrix(p) - eq43).norm(), 1e-9 * eq43.norm());
  // Isotropic Hooke's law with Lame parameters and engineering shear strains (textbook form).
  const double lame = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
  Matrix6d hooke = Matrix6d::Zero();
  hooke.topLeftCorner<3, 3>().setConstant(lame);
  hooke.topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
  hooke.bottomRightCorner<3, 3>().diagonal().setConstant(mu);
  EXPECT_LT((elasticity_matrix(p) - hooke).norm(), 1e-9 * hooke.norm());
  EXPECT_NEAR(shear_modulus(p), mu, 1e-9 * mu);
  const YoungsPoisson back = youngs_poisson_from_lambda_alpha(p);
  EXPECT_NEAR(back.youngs_pa, e, 1e-6);
  EXPECT_NEAR(back.poisson, nu, 1e-12);
  EXPECT_TRUE(is_physically_valid(p));
  EXPECT_FALSE(is_physically_valid({1.0, 0.6}));  // nu = 0.6
  EXPECT_FALSE(validate_youngs_poisson(1e6, 0.5).ok());
  EXPECT_FALSE(validate_youngs_poisson(-1, 0.3).ok());
}

TEST(Polar, MatchesSvdPolarDecomposition) {
  Eigen::Matrix3d s;
  s << 1.2, 0.1, -0.05, 0.1, 0.9, 0.2, -0.05, 0.2, 1.1;  // SPD stretch
  const Eigen::Matrix3d r = random_rotation(2.0, Eigen::Vector3d(1, -2, 0.5));
  const Eigen::Matrix3d f = r * s;
  const Eigen::Matrix3d rp = polar_rotation(f);
  EXPECT_LT((rp - r).norm(), 1e-10);
  // Reference: R = U V^T from the SVD.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  EXPECT_LT((rp - svd.matrixU() * svd.matrixV().transpose()).norm(), 1e-10);
}

TEST(Corotational, FastAssemblyEqualsBtEBOfEq48) {
  const TetMesh mesh = small_box();
  auto fem = CorotationalFem::create(mesh, {});
  ASSERT_TRUE(fem.ok()) << fem.status().to_string();
  std::vector<LambdaAlpha> p(static_cast<size_t>(mesh.num_tets()));
  for (size_t e = 0; e < p.size(); ++e)
    p[e] = lambda_alpha_from_youngs_poisson(1e6 + 1e5 * e, 0.2 + 0.01 * e);
  ASSERT_TRUE(fem->set_params(p).ok());
  // Deform and rotate so that every R_e differs from the identity.
  const Eigen::Matrix3d q = random_rotation(0.7, Eigen::Vector3d(0.3, 1, 0.2));
  MatrixX3d x = mesh.nodes * q.transpose();
  for (Eigen::Index i = 0; i < x.rows(); ++i) x(i, 0) += 0.001 * std::sin(100.0 * i);
  ASSERT_TRUE(fem->set_positions(x).ok());
  fem->update_rotations();
  fem->assemble();
  const Eigen::Index n = fem->num_free_dofs();
  Eigen::MatrixXd dense = Eigen::MatrixXd(fem->stiffness());
  dense = Eigen::MatrixXd(dense.triangularView<Eigen::Upper>()) +
          Eigen::MatrixXd(dense.triangularView<Eigen::StrictlyUpper>()).transpose();
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd rhs_ref = Eigen::VectorXd::Zero(n);
  for (Eigen::Index e = 0; e < mesh.num_tets(); ++e) {
    // K_e = lambda V B^T G B + alpha V B^T H B (Eq. 4.8), warped R K_e R^T; K' x0 = R K_e X_e
    // (A.1).
    const Matrix12d ke = p[static_cast<size_t>(e)].lambda * fem->stiffness_g(e) +
                         p[static_cast<size_t>(e)].alpha * fem->stiffness_h(e);
    EXPECT_LT((ke - fem->element_stiffness(e)).norm(), 1e-9 * ke.norm());
    Matrix12d rot = Matrix12d::Zero();
    for (int a = 0; a < 4; ++a) rot.block<3, 3>(3 * a, 3 * a) = fem->rotation(e);
    const Matrix12d kw = rot * ke * rot.transpose();
    const Vector12d kx0 = rot * ke * fem->rest_positions(e);
    const auto d = fem->element_dofs(e);
    for (int i = 0; i < 12; ++i) {
      rhs_ref(d[i]) += kx0(i);
      for (int j = 0; j < 12; ++j) ref(d[i], d[j]) += kw(i, j);
    }
  }
  EXPECT_LT((dense - ref).norm(), 1e-10 * ref.norm());
  EXPECT_LT((fem->rest_rhs() - rhs_ref).norm(), 1e-10 * rhs_ref.norm());
}

TEST(Corotational, RigidRotationOfRestShapeGivesZeroForceAndStrain) {
  const TetMesh mesh = small_box();
  auto fem = CorotationalFem::create(mesh, {});
  ASSERT_TRUE(fem.ok());
  fem->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.45));
  const Eigen::Matrix3d q = random_rotation(2.5, Eigen::Vector3d(1, 1, -0.4));  // large rotation
  const MatrixX3d x = (mesh.nodes * q.transpose()).rowwise() + Eigen::RowVector3d(0.3, -0.1, 2.0);
  ASSERT_TRUE(fem->set_positions(x).ok());
  fem->update_rotations();
  // Force scale for comparison: E * characteristic area (1 MPa * 1 cm^2 = 100 N).
  EXPECT_LT(fem->elastic_forces().cwiseAbs().maxCoeff(), 1e-9 * 100);
  for (Eigen::Index e = 0; e < mesh.num_tets(); ++e) {
    EXPECT_LT(fem->strain(e).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((fem->rotation(e) - q).norm(), 1e-10);
  }
  // The linear (non-co-rotational) model is not invariant: the same motion produces large forces.
  CorotationalOptions lin;
  lin.corotational = false;
  auto linear = CorotationalFem::create(mesh, {}, lin);
  ASSERT_TRUE(linear.ok());
  linear->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.45));
  ASSERT_TRUE(linear->set_positions(x).ok());
  linear->update_rotations();
  EXPECT_GT(linear->elastic_forces().cwiseAbs().maxCoeff(), 1.0);
}

TEST(Corotational, StrainIsRotationInvariantAndMatchesLinearStrain) {
  const TetMesh mesh = small_box();
  auto fem = CorotationalFem::create(mesh, {});
  ASSERT_TRUE(fem.ok());
  Eigen::Matrix3d s;  // symmetric stretch: its rotated-frame strain is S - I exactly
  s << 1.02, 0.01, 0.0, 0.01, 0.97, 0.005, 0.0, 0.005, 1.01;
  ASSERT_TRUE(fem->set_positions(mesh.nodes * s.transpose()).ok());
  fem->update_rotations();
  const auto eps = fem->strains();
  Vector6d expected;
  expected << 0.02, -0.03, 0.01, 0.02, 0.0, 0.01;  // engineering shears 2 S_ij
  for (Eigen::Index e = 0; e < eps.rows(); ++e) {
    EXPECT_LT((eps.row(e).transpose() - expected).cwiseAbs().maxCoeff(), 1e-12);
  }
  const Eigen::Matrix3d q = random_rotation(1.3, Eigen::Vector3d(-1, 0.2, 0.7));
  ASSERT_TRUE(fem->set_positions(mesh.nodes * (q * s).transpose()).ok());
  fem->update_rotations();
  EXPECT_LT((fem->strains() - eps).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Corotational, PatchTestReproducesLinearFieldsExactly) {
  for (bool corot : {false, true}) {
    auto c = verify_patch(corot);
    ASSERT_TRUE(c.ok()) << c.status().to_string();
    // Exact up to round-off (relative 1e-8 of the displacement; observed ~1e-13).
    EXPECT_LT(c->computed, 1e-8) << c->name;
    EXPECT_TRUE(c->pass);
  }
}

TEST(Corotational, EquilibriumSolveBalancesForces) {
  const TetMesh mesh = small_box();
  auto fem = CorotationalFem::create(mesh, nodes_on_plane(mesh, 0, 0.0, 1e-12));
  ASSERT_TRUE(fem.ok());
  fem->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.3));
  MatrixX3d f = MatrixX3d::Zero(mesh.num_nodes(), 3);
  for (int i : nodes_on_plane(mesh, 0, 0.02, 1e-12)) f(i, 2) = -2.0;  // large: big rotations
  int iterations = 0;
  ASSERT_TRUE(fem->solve_static(f, 200, 1e-12, &iterations).ok());
  const MatrixX3d residual = fem->elastic_forces() + f;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    if (!fem->is_fixed(i)) {
      EXPECT_LT(residual.row(i).norm(), 1e-6) << i;
    }
  }
  // Global equilibrium: the elements pass the whole load to the fixed nodes (support reactions).
  const MatrixX3d fe = fem->elastic_forces();
  Eigen::RowVector3d to_supports = Eigen::RowVector3d::Zero();
  for (int i : fem->fixed_nodes()) to_supports += fe.row(i);
  EXPECT_LT((to_supports - f.colwise().sum()).norm(), 1e-6);
  EXPECT_GT(iterations, 2);
}

// Conjugate gradients on the current K, preconditioned by the factorisation of an earlier one,
// reach the direct solve's positions; without a factorisation, or in too few iterations, they
// report no convergence and leave the positions alone.
TEST(Corotational, PreconditionedSolveMatchesTheDirectSolve) {
  const TetMesh mesh =
      structured_box_mesh(uniform_coordinates(0, 0.04, 8), uniform_coordinates(0, 0.01, 2),
                          uniform_coordinates(0, 0.01, 2));
  auto fem = CorotationalFem::create(mesh, nodes_on_plane(mesh, 0, 0.0, 1e-12));
  ASSERT_TRUE(fem.ok());
  fem->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.3));
  Eigen::VectorXd extra = Eigen::VectorXd::Zero(fem->num_free_dofs());
  for (int i : nodes_on_plane(mesh, 0, 0.04, 1e-12)) extra(fem->dof(i, 2)) = -0.5;
  CorotationalFem::PcgOptions options;
  options.max_iterations = 100;
  options.relative_tolerance = 1e-10;
  CorotationalFem::PcgSummary summary;
  fem->assemble();
  ASSERT_TRUE(fem->solve_preconditioned(extra, options, &summary).ok());
  EXPECT_FALSE(summary.converged);  // nothing factorised yet
  // Factorise K at rest, then bend the beam: the rotations change K.
  ASSERT_TRUE(fem->factorize().ok());
  ASSERT_TRUE(fem->solve(MatrixX3d::Zero(mesh.num_nodes(), 3), extra).ok());
  fem->update_rotations();
  fem->assemble();
  const MatrixX3d start = fem->positions();
  CorotationalFem::PcgOptions one = options;
  one.max_iterations = 1;
  ASSERT_TRUE(fem->solve_preconditioned(extra, one, &summary).ok());
  EXPECT_FALSE(summary.converged);
  EXPECT_EQ(fem->positions(), start);
  ASSERT_TRUE(fem->solve_preconditioned(extra, options, &summary).ok());
  ASSERT_TRUE(summary.converged);
  EXPECT_GT(summary.iterations, 1);
  const MatrixX3d cg = fem->positions();
  ASSERT_TRUE(fem->set_positions(start).ok());
  ASSERT_TRUE(fem->factorize().ok());
  ASSERT_TRUE(fem->solve(MatrixX3d::Zero(mesh.num_nodes(), 3), extra).ok());
  // The tip moves ~mm; CG to 1e-10 in the preconditioned norm agrees to well below a micrometre.
  EXPECT_LT((cg - fem->positions()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT((fem->positions() - start).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(Corotational, BadMeshesAreRejectedWithTheElementNamed) {
  TetMesh mesh = small_box();
  TetMesh inverted = mesh;
  std::swap(inverted.tets(3, 1), inverted.tets(3, 2));
  auto r = CorotationalFem::create(inverted, {0});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("tet 3 is inverted"), std::string::npos)
      << r.status().message();
  TetMesh flat = mesh;
  flat.nodes.row(flat.tets(5, 3)) = flat.nodes.row(flat.tets(5, 0));
  r = CorotationalFem::create(flat, {0});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("degenerate"), std::string::npos) << r.status().message();
  TetMesh nan = mesh;
  nan.nodes(2, 1) = std::nan("");
  EXPECT_FALSE(CorotationalFem::create(nan, {0}).ok());
  TetMesh bad_index = mesh;
  bad_index.tets(0, 0) = 999;
  EXPECT_FALSE(CorotationalFem::create(bad_index, {0}).ok());
  EXPECT_FALSE(CorotationalFem::create(mesh, {-1}).ok());
  // No fixed node: K is singular.
  auto free_body = CorotationalFem::create(mesh, {});
  ASSERT_TRUE(free_body.ok());
  free_body->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.3));
  free_body->assemble();
  EXPECT_EQ(free_body->factorize().code(), StatusCode::kFailedPrecondition);
  // NaN forces.
  auto fem = CorotationalFem::create(mesh, nodes_on_plane(mesh, 0, 0.0, 1e-12));
  ASSERT_TRUE(fem.ok());
  fem->set_uniform_params(lambda_alpha_from_youngs_poisson(1e6, 0.3));
  MatrixX3d f = MatrixX3d::Zero(mesh.num_nodes(), 3);
  f(5, 0) = std::nan("");
  EXPECT_EQ(fem->step(f).code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(fem->set_params({}).ok());
}

}  // namespace
}  // namespace hc::fem
