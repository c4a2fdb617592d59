// Heterogeneous material fit at the thesis's scale (Sec. 4.5: foam block, 1,805 tets, 48 examples;
// issue 3 target <= 5 minutes on this machine): a 50 x 50 x 25 mm block of 10 x 10 x 3 cubes
// (1,800 tets), 48 synthetic examples from a strain-stiffening reference, then fit_heterogeneous
// with the own LM, and (once, for comparison) one example fitted with the own LM and with Ceres.
//
// Run: build/bin/bench_material_fit [--benchmark_filter=...]. Counters: time per stage, errors
// relative to the largest displacement, mean basis size.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>

#include "../unit/material/material_test_util.h"
#include "processing/material/fit.h"

namespace {

using hc::material::testing::box_mesh;
using hc::material::testing::StiffeningReference;

const hc::material::Samples& foam_samples() {
  static const hc::material::Samples samples = [] {
    StiffeningReference ref(box_mesh(10, 10, 3, 0.05, 0.05, 0.025));
    hc::material::SynthOptions o = ref.synth_options(48, 0.0);
    o.probe.radius_m = 0.008;
    o.max_force_n = 6.0;
    auto s = hc::material::synthesize_samples(ref.mesh, ref.simulator(), o);
    hc::material::testing::fixture_check(s.ok(), "synthesize 48 examples");
    return *s;
  }();
  return samples;
}

void BM_FitHeterogeneous1800Tets48Examples(benchmark::State& state) {
  const hc::material::Samples& samples = foam_samples();
  for (auto _ : state) {
    hc::material::HeterogeneousFitOptions options;
    options.parameters.regularization = 1e-6;
    hc::material::HeterogeneousFitSummary summary;
    auto m = hc::material::fit_heterogeneous(samples, options, &summary);
    hc::material::testing::fixture_check(m.ok(), "fit");
    hc::material::RbfMaterial model(*m);
    auto ev = hc::material::evaluate_material(model, samples, {});
    hc::material::testing::fixture_check(ev.ok(), "evaluate");
    state.counters["tets"] = static_cast<double>(samples.mesh.num_tets());
    state.counters["fit_s"] = summary.time_s;
    state.counters["lm_s"] = summary.parameter_time_s;
    state.counters["rbf_s"] = summary.rbf_time_s;
    state.counters["mean_basis"] = summary.mean_basis_size;
    state.counters["fit_rms_rel"] = summary.rms_error_m / samples.max_displacement_m();
    state.counters["eval_rel"] = ev->error_rel_max_disp;
    state.counters["eval_s"] = ev->time_s;
  }
}
BENCHMARK(BM_FitHeterogeneous1800Tets48Examples)->Unit(benchmark::kSecond)->Iterations(1);

void BM_OneExampleOwnVsCeres(benchmark::State& state) {
  const hc::material::Samples& samples = foam_samples();
  const auto backend =
      state.range(0) == 0 ? hc::material::FitBackend::kOwnLm : hc::material::FitBackend::kCeres;
  auto problem = hc::material::ExampleProblem::create(samples.mesh, samples.examples[0]);
  hc::material::testing::fixture_check(problem.ok(), "problem");
  for (auto _ : state) {
    hc::material::ParameterFitOptions options;
    options.regularization = 1e-6;
    options.backend = backend;
    std::vector<hc::fem::LambdaAlpha> p;
    hc::material::ParameterFitSummary s;
    hc::material::testing::fixture_check(
        hc::material::fit_example(&*problem, {problem->stiffness_guess()}, options, &p, &s).ok(),
        "fit_example");
    state.counters["iterations"] = s.iterations;
    state.counters["final_cost"] = s.final_cost;
    state.counters["rms_rel"] = s.rms_error_m / problem->scale_m();
  }
  state.SetLabel(state.range(0) == 0 ? "own LM" : "Ceres");
}
BENCHMARK(BM_OneExampleOwnVsCeres)->Arg(0)->Arg(1)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
