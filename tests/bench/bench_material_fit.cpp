// Heterogeneous material fit at and beyond the thesis's scale (Sec. 4.5: foam block, 1,805 tets, 48
// examples), 50 x 50 x 25 mm blocks, synthetic examples from a strain-stiffening reference:
//
// * BM_FitScaling/<tets>/<joint>: fit_heterogeneous on 48 examples at 1,800 / 3,000 / 10,000 tets,
//   per-example pipeline (joint 0, clean examples) and with the joint material fit (joint 1, 10 %
//   noise, the noise study's settings). Issue 13: time per example no worse than ~linear in the
//   tets; 10,000 tets x 48 examples <= 10 minutes and <= 4 GB peak memory (run it alone under
//   /usr/bin/time -v: --benchmark_filter='BM_FitScaling/9996'). Counters also split the
//   per-example fits' time: the FEM's factorisations (factorize_share) and the rest per ktet.
//   Measured (per-example phase, clean examples): 2.08 / 4.20 / 25.4 s at 1,800 / 3,000 / 9,996
//   tets, 0.024 / 0.029 / 0.053 s per example per ktet; with the joint fit at 9,996 tets 139 s in
//   all (joint phase 121 s), 2.87 GB peak. joint_lm and joint_cg count the joint phase's LM and CG
//   iterations (a slower machine, 2026-11-28: 21 / 21 / 23 LM and 263 / 277 / 420 CG, joint
//   9.7 / 17.5 / 133 s). factor_entries_per_tet: what one solve with an example's factor reads,
//   per tet: 42.8 / 65.5 / 113 (x2.64 over 5.55x the tets; that machine, per-example phase 2.97 /
//   5.03 / 35.7 s, CG per example 108 / 102 / 147): the per-example time per ktet grows with the
//   direct factor's fill, ~n^(1/3) for nested dissection in 3-D, not with the fit's own work.
// * BM_JointNoiseStudy1536/<solver>: the joint phase on the three-layer noise-study block of
//   8 x 8 x 4 cells (1,536 tets), 24 examples from the neo-Hookean reference, 20 % noise; solver 0
//   automatic (matrix-free here), 1 dense (the path that took 944 s in issue 13). Counters:
//   joint_s, the error on the clean examples and the joint LM's final cost. Measured (noise seed
//   2026): joint 83.1 s with block-Jacobi CG (15,338 CG iterations in 43 LM steps, error 1.28 %),
//   4.73 s with RᵀR in the preconditioner (248 in 26, error 1.51 %; over seeds 2026 / 7 / 99 / 1
//   1.51 / 1.35 / 1.25 / 1.30 % against 1.28 / 1.35 / 1.23 / 1.31 %); dense > 1,500 s.
// * BM_OneExampleSolvers/<tets>/<solver>: one example's per-element fit at 600 / 1,152 / 1,800 /
//   3,000 tets, automatic (0) vs dense (1) vs matrix-free (2) vs Ceres (3), the crossover behind
//   FitSolver::kAuto. Measured: matrix-free 0.031 / 0.063 / 0.124 s, dense 0.64 / 3.27 / 11.1 s at
//   600 / 1,152 / 1,800 tets (the same final cost), and automatic chose matrix-free at each.
//
// Run: build/bin/bench_material_fit [--benchmark_filter=...].
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <map>

#include "../unit/material/hyperelastic_reference.h"
#include "../unit/material/material_test_util.h"
#include "processing/fem/corotational.h"
#include "processing/material/fit.h"

namespace {

namespace material = hc::material;
using material::testing::box_mesh;
using material::testing::fixture_check;
using material::testing::StiffeningReference;

hc::TetMesh block(int64_t tets) {
  if (tets <= 700) return box_mesh(5, 5, 4, 0.05, 0.05, 0.025);     // 600
  if (tets <= 1300) return box_mesh(8, 8, 3, 0.05, 0.05, 0.025);    // 1,152
  if (tets <= 2000) return box_mesh(10, 10, 3, 0.05, 0.05, 0.025);  // 1,800
  if (tets <= 5000) return box_mesh(10, 10, 5, 0.05, 0.05, 0.025);  // 3,000
  return box_mesh(17, 14, 7, 0.05, 0.05, 0.025);                    // 9,996
}

const material::Samples& stiffening_samples(int64_t tets) {
  static std::map<int64_t, material::Samples> cache;
  auto it = cache.find(tets);
  if (it != cache.end()) return it->second;
  StiffeningReference ref(block(tets));
  material::SynthOptions o = ref.synth_options(48, 0.0);
  o.probe.radius_m = 0.008;
  o.max_force_n = 6.0;
  auto s = material::synthesize_samples(ref.mesh, ref.simulator(), o);
  fixture_check(s.ok(), "synthesize 48 examples");
  return cache.emplace(tets, *s).first->second;
}

void BM_FitScaling(benchmark::State& state) {
  const material::Samples& clean = stiffening_samples(state.range(0));
  const bool joint = state.range(1) != 0;
  const material::Samples samples = joint ? material::add_displacement_noise(clean, 0.1, 7) : clean;
  for (auto _ : state) {
    material::HeterogeneousFitOptions options;
    if (joint) {
      options.parameters.regularization = 0.01 * 0.1 * 0.1;
      options.parameters.poisson_prior = 0.1;
      options.rbf.max_basis = 3;
      options.joint.enabled = true;
    } else {
      options.parameters.regularization = 1e-6;
    }
    material::HeterogeneousFitSummary summary;
    auto m = material::fit_heterogeneous(samples, options, &summary);
    fixture_check(m.ok(), "fit");
    auto ev = material::evaluate_material(material::RbfMaterial(*m), clean, {});
    fixture_check(ev.ok(), "evaluate");
    const double n = static_cast<double>(samples.examples.size());
    const double ktets = static_cast<double>(samples.mesh.num_tets()) / 1000;
    state.counters["tets"] = static_cast<double>(samples.mesh.num_tets());
    state.counters["fit_s"] = summary.time_s;
    state.counters["per_example_s"] = summary.parameter_time_s;
    state.counters["joint_s"] = summary.joint_time_s;
    state.counters["s_per_example_per_ktet"] = summary.time_s / n / ktets;
    state.counters["eval_rel"] = ev->error_rel_max_disp;
    state.counters["joint_matrix_free"] = summary.joint.matrix_free ? 1 : 0;
    state.counters["joint_cg"] = static_cast<double>(summary.joint.cg_iterations);
    state.counters["joint_lm"] = summary.joint.iterations;
    double lm = 0, cg = 0, matrix_free = 0, factorizations = 0, factorize_s = 0, fit_s = 0;
    for (const material::ParameterFitSummary& e : summary.examples) {
      lm += e.iterations;
      cg += static_cast<double>(e.cg_iterations);
      matrix_free += e.matrix_free ? 1 : 0;
      factorizations += e.fem_factorizations;
      factorize_s += e.fem_factorize_s;
      fit_s += e.time_s;
    }
    state.counters["lm_per_example"] = lm / n;
    state.counters["cg_per_example"] = cg / n;
    // The per-example fits' time split (their summed times, as the fits run in parallel): the
    // FEM's factorisations' share, and the rest of the per-example phase per example per ktet.
    const double share = fit_s > 0 ? factorize_s / fit_s : 0;
    state.counters["factorizations_per_example"] = factorizations / n;
    state.counters["factorize_share"] = share;
    state.counters["rest_s_per_example_per_ktet"] =
        (1 - share) * summary.parameter_time_s / n / ktets;
    state.counters["matrix_free_examples"] = matrix_free;
  }
  // What one solve with an example's factor reads: its entries per tet. A solve costs about as
  // many flops as the factor has entries, and a nested-dissection factor of a 3-D mesh has
  // ~n^(4/3) of them, so the per-example time per ktet can grow as this does. Outside the timed
  // loop: its symbolic analysis is not the fit's.
  hc::Result<hc::fem::CorotationalFem> model =
      hc::fem::CorotationalFem::create(samples.mesh, samples.examples.front().fixed_nodes);
  if (model.ok())
    state.counters["factor_entries_per_tet"] =
        model->cholesky().summary().nnz_factor / static_cast<double>(samples.mesh.num_tets());
}
BENCHMARK(BM_FitScaling)
    ->ArgsProduct({{1800, 3000, 9996}, {0, 1}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

// The shipped noise-study block (processing/material/examples/noise_study_block.json) at 8 x 8 x 4
// cells.
const material::Samples& noise_block_samples() {
  static const material::Samples samples = [] {
    material::testing::HyperelasticReference ref;
    ref.mesh = box_mesh(8, 8, 4, 0.04, 0.04, 0.03);
    ref.layers = {{0.0, 0.01, {150e3, 0.3, 1.0}},
                  {0.01, 0.02, {60e3, 0.35, 4.0}},
                  {0.02, 0.03, {30e3, 0.25, 8.0}}};
    material::SynthOptions o;
    o.examples = 24;
    o.seed = 2026;
    o.probe.shape = "sphere";
    o.probe.radius_m = 0.01;
    o.max_force_n = 3.0;
    o.fixed_nodes = material::testing::bottom_nodes(ref.mesh);
    auto s = material::synthesize_samples(ref.mesh, ref.simulator(), o);
    fixture_check(s.ok(), "synthesize the noise-study block");
    return *s;
  }();
  return samples;
}

void BM_JointNoiseStudy1536(benchmark::State& state) {
  const material::Samples& clean = noise_block_samples();
  const material::Samples noisy = material::add_displacement_noise(clean, 0.2, 2026);
  for (auto _ : state) {
    material::HeterogeneousFitOptions options;
    options.parameters.regularization = 0.01 * 0.2 * 0.2;
    options.parameters.poisson_prior = 0.1;
    options.parameters.solver = static_cast<material::FitSolver>(state.range(0));
    options.rbf.max_basis = 3;
    options.joint.enabled = true;
    options.joint.max_jacobian_bytes = 8e9;  // the dense baseline needs ~1.2 GB
    material::HeterogeneousFitSummary summary;
    auto m = material::fit_heterogeneous(noisy, options, &summary);
    fixture_check(m.ok(), "fit");
    auto ev = material::evaluate_material(material::RbfMaterial(*m), clean, {});
    fixture_check(ev.ok(), "evaluate");
    state.counters["tets"] = static_cast<double>(clean.mesh.num_tets());
    state.counters["per_example_s"] = summary.parameter_time_s;
    state.counters["joint_s"] = summary.joint_time_s;
    state.counters["joint_iterations"] = summary.joint.iterations;
    state.counters["joint_cg"] = static_cast<double>(summary.joint.cg_iterations);
    state.counters["eval_rel"] = ev->error_rel_max_disp;
    state.counters["joint_final_cost"] = summary.joint.final_cost;
  }
  state.SetLabel(state.range(0) == 1 ? "dense" : "auto");
}
BENCHMARK(BM_JointNoiseStudy1536)->Arg(0)->Arg(1)->Unit(benchmark::kSecond)->Iterations(1);

void BM_OneExampleSolvers(benchmark::State& state) {
  const material::Samples& samples = stiffening_samples(state.range(0));
  auto problem = material::ExampleProblem::create(samples.mesh, samples.examples[0]);
  fixture_check(problem.ok(), "problem");
  for (auto _ : state) {
    material::ParameterFitOptions options;
    options.regularization = 1e-6;
    if (state.range(1) == 3) {
      options.backend = material::FitBackend::kCeres;
    } else {
      options.solver = static_cast<material::FitSolver>(state.range(1));
    }
    std::vector<hc::fem::LambdaAlpha> p;
    material::ParameterFitSummary s;
    fixture_check(
        material::fit_example(&*problem, {problem->stiffness_guess()}, options, &p, &s).ok(),
        "fit_example");
    state.counters["iterations"] = s.iterations;
    state.counters["cg"] = static_cast<double>(s.cg_iterations);
    state.counters["final_cost"] = s.final_cost;
    state.counters["rms_rel"] = s.rms_error_m / problem->scale_m();
  }
  static const char* kNames[] = {"auto", "dense", "matrix-free", "Ceres"};
  state.SetLabel(kNames[state.range(1)]);
}
BENCHMARK(BM_OneExampleSolvers)
    ->ArgsProduct({{600, 1152, 1800, 3000}, {0, 1, 2, 3}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
