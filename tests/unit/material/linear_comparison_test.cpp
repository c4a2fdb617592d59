// Thesis Fig. 4.5.2: on a strain-stiffening hyperelastic block probed near its centre, the fitted
// data-driven model follows the reference across force levels, while the average-fit linear
// co-rotational model (one (lambda, alpha) fitted to all examples) underestimates the deformation
// at small forces and overestimates it at large ones.
#include <gtest/gtest.h>

#include <cstdio>

#include "hyperelastic_reference.h"
#include "processing/fem/material_model.h"
#include "processing/material/fit.h"
#include "sanitizer.h"

namespace hc::material {
namespace {

double max_displacement(const TetMesh& mesh, const MatrixX3d& x) {
  return (x - mesh.nodes).rowwise().norm().maxCoeff();
}

TEST(LinearComparison, DataDrivenFollowsReferenceLinearUnderThenOverEstimates) {
  HC_SKIP_WHEN_SANITIZED("~1 min: fits");
  testing::HyperelasticReference ref;
  ref.mesh = testing::box_mesh(4, 4, 2, 0.04, 0.04, 0.02);
  // Foam-like: soft at small strain, strongly stiffening (beta) as it is compressed.
  ref.layers = {{0.0, 0.02, {40e3, 0.25, 30.0}}};
  SynthOptions o;
  o.probe.shape = "sphere";
  o.probe.radius_m = 0.01;
  o.max_force_n = 6.0;
  o.min_force_fraction = 0.1;
  o.margin_fraction = 0.4;  // probe near the centre, as in the thesis's 12 examples
  o.fixed_nodes = testing::bottom_nodes(ref.mesh);
  o.examples = 12;  // the thesis's 12 examples near the centre
  o.seed = 5;
  Result<Samples> train = synthesize_samples(ref.mesh, ref.simulator(), o);
  ASSERT_TRUE(train.ok()) << train.status().to_string();

  HeterogeneousFitOptions options;
  options.parameters.regularization = 1e-6;
  options.rbf.tolerance = 0.01;  // noise-free examples: reproduce them closely
  Result<Material> fitted = fit_heterogeneous(*train, options);
  ASSERT_TRUE(fitted.ok()) << fitted.status().to_string();
  std::vector<ExampleProblem> problems;
  std::vector<ExampleProblem*> ptrs;
  for (const Example& ex : train->examples) {
    Result<ExampleProblem> p = ExampleProblem::create(train->mesh, ex);
    ASSERT_TRUE(p.ok());
    problems.push_back(std::move(p).value());
  }
  for (auto& p : problems) ptrs.push_back(&p);
  Result<fem::LambdaAlpha> average = fit_homogeneous(ptrs, options.parameters);
  ASSERT_TRUE(average.ok());

  // Test loads: centre, a small, a medium and a large force (not among the training examples).
  o.examples = 1;
  o.margin_fraction = 0.499;  // the centre, to 0.1 mm
  RbfMaterial ours(*fitted);
  fem::ConstantMaterial linear(*average);
  std::vector<double> ratio_ours, ratio_linear;
  for (double force : {0.6, 2.5, 6.0}) {
    o.max_force_n = force;
    o.min_force_fraction = 1.0;
    Result<Samples> test = synthesize_samples(ref.mesh, ref.simulator(), o);
    ASSERT_TRUE(test.ok()) << test.status().to_string();
    const double u_ref = test->max_displacement_m();
    Result<EvaluateSummary> a = evaluate_material(ours, *test, {});
    Result<EvaluateSummary> b = evaluate_material(linear, *test, {});
    ASSERT_TRUE(a.ok() && b.ok());
    const double u_ours = max_displacement(ref.mesh, a->positions[0]);
    const double u_lin = max_displacement(ref.mesh, b->positions[0]);
    std::printf("force %.1f N: reference %.3f mm, data-driven %.3f mm, average linear %.3f mm\n",
                force, 1e3 * u_ref, 1e3 * u_ours, 1e3 * u_lin);
    ratio_ours.push_back(u_ours / u_ref);
    ratio_linear.push_back(u_lin / u_ref);
  }
  // Ours follows the reference (max displacement within 10 % at every force level) and beats the
  // linear model at both ends. Measured: ours 0.91, 1.05, 1.09 of the reference at 0.6, 2.5, 6 N;
  // the linear model 0.69, 1.44, 2.60 (0.6 N lies at the lower end of the training forces, 0.6-6
  // N, and 6 N compresses the block by ~30 %). Before the nodal-force fixed point was
  // under-relaxed (processing/fem/incremental.cpp) and with 8 examples ours was 0.75 / 1.05 / 1.15.
  for (double r : ratio_ours) EXPECT_NEAR(r, 1.0, 0.10);
  EXPECT_LT(std::abs(ratio_ours.front() - 1), std::abs(ratio_linear.front() - 1));
  EXPECT_LT(std::abs(ratio_ours.back() - 1), std::abs(ratio_linear.back() - 1));
  // The linear model: underestimates at small force, overestimates at large force (Fig. 4.5.2).
  EXPECT_LT(ratio_linear.front(), 1.0);
  EXPECT_GT(ratio_linear.back(), 1.0);
}

}  // namespace
}  // namespace hc::material
