// The matrix-free Gauss–Newton / Levenberg–Marquardt path of the material fits (fit.h,
// FitSolver): Jacobian products by one FEM solve each, checked against the dense Appendix A
// Jacobian and against finite differences, and the fits of both paths compared at convergence.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "material_test_util.h"
#include "processing/fem/material_model.h"
#include "processing/material/fit.h"

namespace hc::material {
namespace {

using Block = testing::TwoLayerBlock;  // pressed off-centre in the tests below

TEST(MatrixFree, JacobianProductsMatchTheDenseJacobianAndFiniteDifferences) {
  Block b;
  Example ex = b.example(0.02, 0.02, Eigen::Vector3d(0.3, 0.2, -2.0));
  ex.visible[30] = ex.visible[31] = 0;  // occluded nodes: not measured
  Result<ExampleProblem> problem = ExampleProblem::create(b.mesh, ex);
  ASSERT_TRUE(problem.ok()) << problem.status().to_string();
  std::mt19937 rng(11);
  const std::vector<fem::LambdaAlpha> p = b.perturbed(&rng);
  Eigen::VectorXd r0;
  ASSERT_TRUE(problem->simulate(p, &r0).ok());
  Eigen::MatrixXd j;
  ASSERT_TRUE(problem->jacobian(&j).ok());
  // A direction in (λ, α) with every element's entries scaled like its parameters.
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::VectorXd v(j.cols());
  for (std::size_t e = 0; e < p.size(); ++e) {
    v(2 * static_cast<Eigen::Index>(e)) = normal(rng) * p[e].lambda;
    v(2 * static_cast<Eigen::Index>(e) + 1) = normal(rng) * p[e].alpha;
  }
  Eigen::VectorXd w = Eigen::VectorXd::Zero(j.rows());
  for (Eigen::Index i = 0; i < w.size(); ++i) w(i) = normal(rng);
  Eigen::VectorXd jv, jtw;
  ASSERT_TRUE(problem->apply_jacobian(v, &jv).ok());
  ASSERT_TRUE(problem->apply_jacobian_transpose(w, &jtw).ok());
  // Same Appendix A Jacobian, one solve each instead of min(rows, columns) solves: round-off only.
  EXPECT_LE((jv - j * v).norm(), 1e-10 * (j * v).norm());
  EXPECT_LE((jtw - j.transpose() * w).norm(), 1e-10 * (j.transpose() * w).norm());
  Eigen::MatrixXd w3(j.rows(), 3), jtw3;
  for (Eigen::Index c = 0; c < 3; ++c)
    for (Eigen::Index i = 0; i < w3.rows(); ++i) w3(i, c) = normal(rng);
  ASSERT_TRUE(problem->apply_jacobian_transpose(w3, &jtw3).ok());
  EXPECT_LE((jtw3 - j.transpose() * w3).norm(), 1e-10 * (j.transpose() * w3).norm());
  // Appendix A's check for the matrix-free path: J v against central differences of the residual
  // along v (relative error <= 1e-6, as for the dense Jacobian in fit_test.cpp).
  const double h = 1e-5;
  std::vector<fem::LambdaAlpha> pp = p, pm = p;
  for (std::size_t e = 0; e < p.size(); ++e) {
    pp[e].lambda += h * v(2 * static_cast<Eigen::Index>(e));
    pp[e].alpha += h * v(2 * static_cast<Eigen::Index>(e) + 1);
    pm[e].lambda -= h * v(2 * static_cast<Eigen::Index>(e));
    pm[e].alpha -= h * v(2 * static_cast<Eigen::Index>(e) + 1);
  }
  Eigen::VectorXd rp, rm;
  ASSERT_TRUE(problem->simulate(pp, &rp).ok());
  ASSERT_TRUE(problem->simulate(pm, &rm).ok());
  const Eigen::VectorXd fd = (rp - rm) / (2 * h);
  EXPECT_LE((jv - fd).norm(), 1e-6 * fd.norm());
}

TEST(MatrixFree, PerExampleFitAgreesWithTheDensePath) {
  Block b;
  const Example ex = b.example(0.015, 0.025, Eigen::Vector3d(0.5, 0, -3.0));
  Result<ExampleProblem> problem = ExampleProblem::create(b.mesh, ex);
  ASSERT_TRUE(problem.ok());
  ParameterFitOptions options;
  options.regularization = 1e-3;
  options.poisson_prior = 0.1;
  options.max_iterations = 200;
  options.function_tolerance = 0;  // run to the parameter tolerance
  options.parameter_tolerance = 1e-11;
  options.cg_relative_tolerance = 1e-12;
  options.cg_max_iterations = 2000;
  const fem::LambdaAlpha start = problem->stiffness_guess();
  std::vector<fem::LambdaAlpha> dense, free;
  ParameterFitSummary ds, fs;
  options.solver = FitSolver::kDense;
  ASSERT_TRUE(fit_example(&*problem, {start}, options, &dense, &ds).ok());
  options.solver = FitSolver::kMatrixFree;
  ASSERT_TRUE(fit_example(&*problem, {start}, options, &free, &fs).ok());
  EXPECT_FALSE(ds.matrix_free);
  EXPECT_TRUE(fs.matrix_free);
  EXPECT_GT(fs.cg_iterations, 0);
  // The bound: the same minimiser, parameters within 1e-6 relative.
  double worst = 0;
  for (std::size_t e = 0; e < dense.size(); ++e) {
    worst = std::max(worst, std::abs(free[e].lambda / dense[e].lambda - 1));
    worst = std::max(worst, std::abs(free[e].alpha / dense[e].alpha - 1));
  }
  EXPECT_LE(worst, 1e-6) << "dense: " << ds.message << " (" << ds.iterations
                         << " it), matrix-free: " << fs.message << " (" << fs.iterations << " it)";
  EXPECT_NEAR(fs.final_cost, ds.final_cost, 1e-9 * ds.final_cost);
}

TEST(MatrixFree, JointFitAgreesWithTheDensePath) {
  Block b;
  std::vector<Example> examples = {b.example(0.015, 0.02, Eigen::Vector3d(0, 0, -3.0)),
                                   b.example(0.025, 0.025, Eigen::Vector3d(0.4, 0, -2.5)),
                                   b.example(0.02, 0.012, Eigen::Vector3d(0, -0.3, -3.5))};
  std::vector<ExampleProblem> problems;
  std::vector<std::vector<fem::LambdaAlpha>> start;
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 6>> strains;
  for (const Example& ex : examples) {
    Result<ExampleProblem> p = ExampleProblem::create(b.mesh, ex);
    ASSERT_TRUE(p.ok());
    Eigen::VectorXd r;
    start.emplace_back(static_cast<std::size_t>(b.mesh.num_tets()), p->stiffness_guess());
    ASSERT_TRUE(p->simulate(start.back(), &r).ok());
    strains.push_back(p->strains());
    problems.push_back(std::move(p).value());
  }
  const auto fit = [&](FitSolver solver, ParameterFitSummary* s) {
    std::vector<ExampleProblem*> ptrs;
    for (ExampleProblem& p : problems) ptrs.push_back(&p);
    auto st = strains;
    ParameterFitOptions parameters;
    parameters.regularization = 1e-4;
    parameters.poisson_prior = 0.1;
    parameters.solver = solver;
    parameters.parameter_tolerance = 1e-11;
    parameters.cg_relative_tolerance = 1e-12;
    parameters.cg_max_iterations = 4000;
    JointRefinementOptions joint;
    joint.passes = 1;
    joint.max_iterations = 200;
    joint.function_tolerance = 0;
    return fit_joint_material(ptrs, &st, start, parameters, joint, s);
  };
  ParameterFitSummary ds, fs;
  Result<Material> dense = fit(FitSolver::kDense, &ds);
  Result<Material> free = fit(FitSolver::kMatrixFree, &fs);
  ASSERT_TRUE(dense.ok()) << dense.status().to_string();
  ASSERT_TRUE(free.ok()) << free.status().to_string();
  EXPECT_TRUE(fs.matrix_free);
  std::printf("matrix-free joint fit: %d LM iterations, %ld CG iterations (dense: %d LM)\n",
              fs.iterations, fs.cg_iterations, ds.iterations);
  // Every element's material (base stiffness, Poisson's ratio in the constant term; stiffening
  // weights) within 1e-6 relative of the dense path's (weights relative to the base stiffness).
  double worst = 0;
  for (std::size_t e = 0; e < dense->rbfs.size(); ++e) {
    const StrainRbf& d = dense->rbfs[e];
    const StrainRbf& f = free->rbfs[e];
    const double scale = d.lambda_floor_pa;
    worst = std::max(worst, std::abs(f.lambda_floor_pa / scale - 1));
    worst = std::max(worst, (f.constant - d.constant).norm() / d.constant.norm());
    worst = std::max(worst, (f.weights - d.weights).cwiseAbs().maxCoeff() / scale);
  }
  EXPECT_LE(worst, 1e-6) << "dense " << ds.message << " " << ds.iterations << " it; matrix-free "
                         << fs.message << " " << fs.iterations << " it";
}

}  // namespace
}  // namespace hc::material
