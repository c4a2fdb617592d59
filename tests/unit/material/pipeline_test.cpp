// The heterogeneous pipeline end to end on a small block: synthesize examples with a strain-
// stiffening co-rotational reference (processing/fem's LinearStrainMaterial under probe contact),
// fit (per-example LM + per-element RBF), and evaluate by incremental loading.
#include <gtest/gtest.h>

#include "material_test_util.h"
#include "processing/fem/incremental.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"
#include "processing/material/fit.h"
#include "processing/material/synth.h"

namespace hc::material {
namespace {

using testing::bottom_nodes;
using testing::box_mesh;

// Stiffening reference: lambda, alpha grow with compression (eps_zz < 0) of each element.
struct StiffeningReference {
  TetMesh mesh = box_mesh(4, 4, 2, 0.04, 0.04, 0.02);
  fem::LambdaAlpha p0 = fem::lambda_alpha_from_youngs_poisson(60e3, 0.3);
  fem::LinearStrainMaterial material{p0, (Vector6d() << 0, 0, -20 * p0.lambda, 0, 0, 0).finished(),
                                     (Vector6d() << 0, 0, -20 * p0.alpha, 0, 0, 0).finished()};

  // The "probe" is a pressure patch: the force spread equally over the top nodes within the probe
  // radius of its axis (keeps this test independent of contact convergence), simulated by
  // incremental loading with the stiffening material.
  ReferenceSimulator simulator() const {
    return [this](const ProbePose& pose, double force_n) -> Result<ReferenceIndentation> {
      HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                          fem::CorotationalFem::create(mesh, bottom_nodes(mesh)));
      const std::vector<int> loaded =
          testing::top_nodes_near(mesh, pose.position_m.x(), pose.position_m.y(), pose.radius_m);
      if (loaded.empty()) return invalid_argument("probe misses the top nodes");
      MatrixX3d forces = MatrixX3d::Zero(mesh.num_nodes(), 3);
      for (int n : loaded) forces.row(n) = force_n / loaded.size() * pose.direction.transpose();
      fem::IncrementalOptions io;
      io.steps = 6;
      io.update_within_step = true;
      fem::IncrementalSummary is;
      HC_RETURN_IF_ERROR(fem::run_incremental_forces(&f, material, forces, io, &is));
      ReferenceIndentation out;
      out.positions_m = f.positions();
      out.contact_forces_n = forces;
      return out;
    };
  }
  SynthOptions synth_options(int examples, double noise) const {
    SynthOptions o;
    o.examples = examples;
    o.noise = noise;
    o.seed = 11;
    o.probe.shape = "sphere";
    o.probe.radius_m = 0.011;
    o.max_force_n = 4.0;
    o.fixed_nodes = bottom_nodes(mesh);
    return o;
  }
};

TEST(Synth, SameSeedGivesSameExamplesAndNoiseHasTheRequestedSize) {
  StiffeningReference ref;
  Result<Samples> clean = synthesize_samples(ref.mesh, ref.simulator(), ref.synth_options(4, 0));
  ASSERT_TRUE(clean.ok()) << clean.status().to_string();
  Result<Samples> noisy = synthesize_samples(ref.mesh, ref.simulator(), ref.synth_options(4, 0.2));
  ASSERT_TRUE(noisy.ok());
  ASSERT_EQ(clean->examples.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    const Example& c = clean->examples[i];
    const Example& n = noisy->examples[i];
    EXPECT_TRUE(c.probe.position_m.isApprox(n.probe.position_m));
    ASSERT_EQ(c.forces.size(), n.forces.size());
    // Total contact force = the requested level (force control tolerance 1e-4 relative).
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (const auto& f : c.forces) total += f.force_n;
    EXPECT_GE(-total.z(), 0.2 * 4.0 * (1 - 1e-3));
    EXPECT_LE(-total.z(), 4.0 * (1 + 1e-3));
    // Noise: per-coordinate standard deviation 0.2 x the example's max displacement (sample
    // estimate over ~(#free nodes x 3) draws, within 15 %).
    const double sigma = 0.2 * clean->max_displacement_m(i);
    double sum = 0;
    int count = 0;
    for (Eigen::Index k = 0; k < ref.mesh.num_nodes(); ++k) {
      if (std::binary_search(c.fixed_nodes.begin(), c.fixed_nodes.end(), static_cast<int>(k))) {
        EXPECT_TRUE(n.positions_m.row(k).isApprox(ref.mesh.nodes.row(k)));
        continue;
      }
      sum += (n.positions_m.row(k) - c.positions_m.row(k)).squaredNorm();
      count += 3;
    }
    EXPECT_NEAR(std::sqrt(sum / count), sigma, 0.15 * sigma);
  }
}

TEST(Pipeline, FitsAndReproducesNoiseFreeExamples) {
  StiffeningReference ref;
  Result<Samples> samples = synthesize_samples(ref.mesh, ref.simulator(), ref.synth_options(9, 0));
  ASSERT_TRUE(samples.ok()) << samples.status().to_string();
  HeterogeneousFitOptions options;
  options.parameters.regularization = 1e-6;
  HeterogeneousFitSummary summary;
  Result<Material> material = fit_heterogeneous(*samples, options, &summary);
  ASSERT_TRUE(material.ok()) << material.status().to_string();
  EXPECT_EQ(material->rbfs.size(), static_cast<std::size_t>(ref.mesh.num_tets()));
  EXPECT_GE(summary.mean_basis_size, 1.0);
  const double umax = samples->max_displacement_m();
  EXPECT_LT(summary.rms_error_m, 0.01 * umax);
  RbfMaterial model(*material);
  EvaluateOptions eo;
  Result<EvaluateSummary> ev = evaluate_material(model, *samples, eo);
  ASSERT_TRUE(ev.ok()) << ev.status().to_string();
  std::printf("fit rms %.3g m, eval rms %.3g m (%.2f %% of max disp %.3g m), basis %.2f, %.2f s\n",
              summary.rms_error_m, ev->rms_error_m, 100 * ev->error_rel_max_disp, umax,
              summary.mean_basis_size, summary.time_s);
  // Thesis Sec. 4.5: 0.3 % of the max displacement without noise.
  EXPECT_LT(ev->error_rel_max_disp, 0.003);
}

}  // namespace
}  // namespace hc::material
