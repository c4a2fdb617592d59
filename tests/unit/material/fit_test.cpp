// Per-example parameter estimation (thesis Sec. 4.3.1, Eq. 4.10, Appendix A).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <random>

#include "material_test_util.h"
#include "processing/fem/material_model.h"
#include "processing/material/fit.h"

namespace hc::material {
namespace {

using testing::box_mesh;
using testing::simulate_example;
using testing::top_nodes_near;

using TwoLayer = testing::TwoLayerBlock;

// The two-layer block pressed by `force` (N) at its top centre, as one example's fit problem.
ExampleProblem pressed_problem(const TwoLayer& b, const Eigen::Vector3d& force) {
  Result<ExampleProblem> problem = ExampleProblem::create(b.mesh, b.example(0.02, 0.02, force));
  testing::fixture_check(problem.ok(), "the pressed two-layer block's problem");
  return std::move(problem).value();
}

// The two-layer block pressed by (0.5, 0, -3) N, to be fitted from its stiffness guess under a
// weak regulariser: what the FitExample comparisons below start from.
struct PressedFit {
  TwoLayer b;
  ExampleProblem problem = pressed_problem(b, Eigen::Vector3d(0.5, 0, -3.0));
  ParameterFitOptions options = [] {
    ParameterFitOptions o;
    o.regularization = 1e-4;
    return o;
  }();
  fem::LambdaAlpha start = problem.stiffness_guess();
};

TEST(ExampleProblem, JacobianMatchesCentralDifferences) {
  // Appendix A's analytic Jacobian vs central differences, relative error <= 1e-6 (issue 3).
  TwoLayer b;
  Example ex = b.example(0.02, 0.02, Eigen::Vector3d(0.3, 0.2, -2.0));
  // Occlude a few nodes so that the rotation reference mixes measured and simulated positions.
  ex.visible[30] = ex.visible[31] = 0;
  Result<ExampleProblem> problem = ExampleProblem::create(b.mesh, ex);
  ASSERT_TRUE(problem.ok()) << problem.status().to_string();
  std::mt19937 rng(7);
  const std::vector<fem::LambdaAlpha> p = b.perturbed(&rng);
  Eigen::VectorXd r0;
  ASSERT_TRUE(problem->simulate(p, &r0).ok());
  Eigen::MatrixXd j;
  ASSERT_TRUE(problem->jacobian(&j).ok());
  ASSERT_EQ(j.cols(), 2 * b.mesh.num_tets());
  // Both solve strategies (few columns: grouped; many columns: Z = K⁻¹ Sᵀ) must agree.
  std::vector<int> groups(static_cast<std::size_t>(b.mesh.num_tets()));
  for (std::size_t e = 0; e < groups.size(); ++e) groups[e] = static_cast<int>(e % 3);
  Eigen::MatrixXd jg;
  ASSERT_TRUE(problem->jacobian(&jg, &groups, 3).ok());
  for (int g = 0; g < 3; ++g) {
    Eigen::VectorXd sum_l = Eigen::VectorXd::Zero(j.rows()), sum_a = sum_l;
    for (std::size_t e = 0; e < groups.size(); ++e)
      if (groups[e] == g) {
        sum_l += j.col(2 * static_cast<Eigen::Index>(e));
        sum_a += j.col(2 * static_cast<Eigen::Index>(e) + 1);
      }
    EXPECT_LE((jg.col(2 * g) - sum_l).norm(), 1e-9 * sum_l.norm());
    EXPECT_LE((jg.col(2 * g + 1) - sum_a).norm(), 1e-9 * sum_a.norm());
  }
  double worst = 0;
  for (Eigen::Index e : {0L, 5L, 40L, 100L, 150L, 191L}) {
    for (int c = 0; c < 2; ++c) {
      const double h = 1e-4 * p[static_cast<std::size_t>(e)].lambda;
      auto pp = p, pm = p;
      (c == 0 ? pp[static_cast<std::size_t>(e)].lambda : pp[static_cast<std::size_t>(e)].alpha) +=
          h;
      (c == 0 ? pm[static_cast<std::size_t>(e)].lambda : pm[static_cast<std::size_t>(e)].alpha) -=
          h;
      Eigen::VectorXd rp, rm;
      ASSERT_TRUE(problem->simulate(pp, &rp).ok());
      ASSERT_TRUE(problem->simulate(pm, &rm).ok());
      const Eigen::VectorXd fd = (rp - rm) / (2 * h);
      const double rel = (j.col(2 * e + c) - fd).norm() / fd.norm();
      worst = std::max(worst, rel);
      EXPECT_LE(rel, 1e-6) << "element " << e << " parameter " << c;
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(ExampleProblem, RefusesUnusableExamples) {
  TwoLayer b;
  Example ex = b.example(0.02, 0.02, Eigen::Vector3d(0, 0, -1));
  Example no_fixed = ex;
  no_fixed.fixed_nodes.clear();
  EXPECT_FALSE(ExampleProblem::create(b.mesh, no_fixed).ok());
  Example invisible = ex;
  std::fill(invisible.visible.begin(), invisible.visible.end(), 0);
  EXPECT_FALSE(ExampleProblem::create(b.mesh, invisible).ok());
  Example opposite = ex;  // displacements against the force: no positive stiffness explains them
  opposite.positions_m = 2 * b.mesh.nodes - ex.positions_m;
  Result<ExampleProblem> p = ExampleProblem::create(b.mesh, opposite);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.status().message().find("do not follow"), std::string::npos);
}

TEST(FitExample, RecoversLayeredStiffnessFromNoiseFreeData) {
  TwoLayer b;
  const Example ex = b.example(0.02, 0.02, Eigen::Vector3d(0, 0, -3.0));
  Result<ExampleProblem> problem = ExampleProblem::create(b.mesh, ex);
  ASSERT_TRUE(problem.ok());
  ParameterFitOptions options;
  options.regularization = 1e-9;
  ParameterFitSummary hs;
  Result<fem::LambdaAlpha> uniform = fit_homogeneous({&*problem}, options, &hs);
  ASSERT_TRUE(uniform.ok());
  // The uniform fit lies between the two layers.
  EXPECT_GT(uniform->lambda, b.truth[0].lambda * 0.2);
  std::vector<fem::LambdaAlpha> p;
  ParameterFitSummary s;
  ASSERT_TRUE(fit_example(&*problem, {*uniform}, options, &p, &s).ok());
  const double umax = problem->scale_m();
  // Noise-free data from the same model family: positions reproduced to 1 % of the displacement,
  // far better than the uniform model.
  EXPECT_LT(s.rms_error_m, 0.01 * umax) << s.message;
  EXPECT_LT(s.rms_error_m, 0.25 * hs.rms_error_m);
  for (const auto& x : p) EXPECT_TRUE(fem::is_physically_valid(x));
  EXPECT_GT(s.iterations, 0);
}

// fit_heterogeneous shares one ExampleFitSetup (the regulariser and the coarse space) among its
// examples: a fit with a shared setup must be the fit without one, and a setup made for other
// options or another mesh must be refused. The matrix-free path is forced so the coarse space is
// made and used; the FEM's factorisations are counted (one per residual, so at least one per LM
// iteration) and timed within the fit's time.
TEST(FitExample, SharedSetupGivesTheSameFitAndRefusesAnotherMeshOrOptions) {
  PressedFit f;
  ParameterFitOptions& options = f.options;
  options.poisson_prior = 0.1;
  options.solver = FitSolver::kMatrixFree;
  std::vector<fem::LambdaAlpha> own, shared;
  ParameterFitSummary so, ss;
  ASSERT_TRUE(fit_example(&f.problem, {f.start}, options, &own, &so).ok());
  Result<std::shared_ptr<const ExampleFitSetup>> setup = make_example_fit_setup(f.b.mesh, options);
  ASSERT_TRUE(setup.ok());
  ASSERT_TRUE(fit_example(&f.problem, {f.start}, options, &shared, &ss, setup->get()).ok());
  EXPECT_TRUE(so.matrix_free);
  EXPECT_EQ(so.cg_iterations, ss.cg_iterations);
  ASSERT_EQ(own.size(), shared.size());
  for (std::size_t e = 0; e < own.size(); ++e) {
    EXPECT_EQ(own[e].lambda, shared[e].lambda) << e;
    EXPECT_EQ(own[e].alpha, shared[e].alpha) << e;
  }
  EXPECT_GE(ss.fem_factorizations, ss.iterations);
  EXPECT_GT(ss.fem_factorize_s, 0.0);
  EXPECT_LE(ss.fem_factorize_s, ss.time_s);

  ParameterFitOptions other = options;
  other.regularization = 2e-4;
  const Status wrong_options =
      fit_example(&f.problem, {f.start}, other, &shared, &ss, setup->get());
  EXPECT_EQ(wrong_options.code(), StatusCode::kInvalidArgument) << wrong_options.message();
  TetMesh smaller = f.b.mesh;
  smaller.tets.conservativeResize(smaller.tets.rows() - 1, 4);
  Result<std::shared_ptr<const ExampleFitSetup>> other_mesh =
      make_example_fit_setup(smaller, options);
  ASSERT_TRUE(other_mesh.ok());
  const Status wrong_mesh =
      fit_example(&f.problem, {f.start}, options, &shared, &ss, other_mesh->get());
  EXPECT_EQ(wrong_mesh.code(), StatusCode::kInvalidArgument) << wrong_mesh.message();
}

TEST(FitExample, OwnLmAndCeresReachTheSameCost) {
  PressedFit f;
  ParameterFitOptions& options = f.options;
  options.max_iterations = 30;
  std::vector<fem::LambdaAlpha> p_own, p_ceres;
  ParameterFitSummary own, ceres;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(fit_example(&f.problem, {f.start}, options, &p_own, &own).ok());
  const auto t1 = std::chrono::steady_clock::now();
  options.backend = FitBackend::kCeres;
  ASSERT_TRUE(fit_example(&f.problem, {f.start}, options, &p_ceres, &ceres).ok());
  const auto t2 = std::chrono::steady_clock::now();
  EXPECT_TRUE(ceres.usable) << ceres.message;
  // Same objective (Eq. 4.10); both optimisers must get within 5 % of each other's final cost.
  EXPECT_LE(own.final_cost, 1.05 * ceres.final_cost + 1e-12);
  EXPECT_LE(ceres.final_cost, 1.05 * own.final_cost + 1e-12);
  RecordProperty("own_lm_s", std::to_string(std::chrono::duration<double>(t1 - t0).count()));
  RecordProperty("ceres_s", std::to_string(std::chrono::duration<double>(t2 - t1).count()));
  std::printf("own LM %.3f s (%d it, cost %.4g), Ceres %.3f s (%d it, cost %.4g)\n",
              std::chrono::duration<double>(t1 - t0).count(), own.iterations, own.final_cost,
              std::chrono::duration<double>(t2 - t1).count(), ceres.iterations, ceres.final_cost);
}

TEST(Laplacian, UmbrellaWeightsCountVertexNeighbours) {
  // Two tets sharing a face plus one touching at a single vertex: all pairs share a vertex.
  TetMesh m;
  m.nodes.resize(7, 3);
  m.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1, 5, 5, 5, 6, 5, 5;
  m.tets.resize(3, 4);
  m.tets << 0, 1, 2, 3, 1, 4, 2, 3, 4, 5, 6, 0;
  const Eigen::MatrixXd l = Eigen::MatrixXd(tet_umbrella_laplacian(m));
  Eigen::MatrixXd expected(3, 3);
  expected << 2, -1, -1, -1, 2, -1, -1, -1, 2;
  EXPECT_TRUE(l.isApprox(expected));
  EXPECT_NEAR(l.rowwise().sum().norm(), 0, 1e-15);  // constants are in the null space
  // Face adjacency: only tets 0 and 1 share a face (1, 2, 3); tet 2 has no face neighbour.
  const Eigen::MatrixXd lf = Eigen::MatrixXd(tet_umbrella_laplacian(m, TetAdjacency::kFace));
  expected << 1, -1, 0, -1, 1, 0, 0, 0, 0;
  EXPECT_TRUE(lf.isApprox(expected)) << lf;
}

TEST(Laplacian, FaceNeighboursOfABoxMesh) {
  // 3 x 2 x 2 cubes, 6 tets each: every tet has 4 faces; the boundary has 2 triangles per cube
  // face, 2 (3·2 + 2·2 + 3·2) · 2 = 64, so the degrees sum to 4 T − 64 (each interior face counted
  // from both sides); no tet has more than 4 face neighbours and L is symmetric.
  const TetMesh m = testing::box_mesh(3, 2, 2, 0.03, 0.02, 0.02);
  const Eigen::MatrixXd l = Eigen::MatrixXd(tet_umbrella_laplacian(m, TetAdjacency::kFace));
  const auto t = static_cast<double>(m.num_tets());
  EXPECT_EQ(m.num_tets(), 72);
  EXPECT_DOUBLE_EQ(l.diagonal().sum(), 4 * t - 64);
  EXPECT_LE(l.diagonal().maxCoeff(), 4);
  EXPECT_GE(l.diagonal().minCoeff(), 1);
  EXPECT_TRUE(l.isApprox(l.transpose()));
  EXPECT_NEAR(l.rowwise().sum().norm(), 0, 1e-15);
  // The vertex stencil is much wider on the same mesh.
  const Eigen::MatrixXd lv = Eigen::MatrixXd(tet_umbrella_laplacian(m));
  EXPECT_GT(lv.diagonal().minCoeff(), l.diagonal().maxCoeff());
}

}  // namespace
}  // namespace hc::material
