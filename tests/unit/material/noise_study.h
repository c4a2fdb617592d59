// The thesis's noise study (Sec. 4.5): its noise levels and reported mean errors, and the one fit
// that noise_study_test.cpp (the shipped block) and noise_study_blocks_test.cpp (other blocks) run.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>

#include "processing/material/fit.h"

namespace hc::material::testing {

// Thesis Sec. 4.5 ("On average, we obtain an error of 0.3 % ... 2.1 %, 3.1 % and 4.4 %").
inline constexpr double kNoise[] = {0.0, 0.1, 0.2, 0.3};
inline constexpr double kThesis[] = {0.003, 0.021, 0.031, 0.044};

// The fit's settings at a noise level (σ as a fraction of the max displacement). Noise-free: weak
// smoothing, rich basis. Noisy: Tikhonov weight growing with the noise variance (γ = 0.01 σ²), a
// small basis, a weak prior on Poisson's ratio, which displacement data hardly identify (see
// fit.h), and the joint material fit over all examples (its defaults).
inline HeterogeneousFitOptions noise_study_options(double noise) {
  HeterogeneousFitOptions options;
  if (noise == 0) {
    options.parameters.regularization = 1e-8;
    options.rbf.tolerance = 0.02;
  } else {
    options.parameters.regularization = 0.01 * noise * noise;
    options.parameters.poisson_prior = 0.1;
    options.rbf.max_basis = 3;
    options.joint.enabled = true;
  }
  // The dense LM (the thesis's path): the matrix-free one stops at a point of the joint fit's flat
  // valley that moves with rounding (one 30 % stream: 3.26 % alone, 4.95 % after other fits in
  // the same process changed OpenBLAS's threads), too unsteady for bounds on single draws.
  options.parameters.solver = FitSolver::kDense;
  return options;
}

// error_rel_max_disp of the material fitted to `clean` with noise `noise` (stream `seed`),
// evaluated on the clean examples; 1 (and a test failure) when the fit or evaluation fails.
inline double noise_study_error(const Samples& clean, double noise, std::uint64_t seed,
                                HeterogeneousFitSummary* fs) {
  const Samples noisy = add_displacement_noise(clean, noise, seed);
  Result<Material> m = fit_heterogeneous(noisy, noise_study_options(noise), fs);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  if (!m.ok()) return 1.0;
  Result<EvaluateSummary> ev = evaluate_material(RbfMaterial(*m), clean, {});
  EXPECT_TRUE(ev.ok()) << ev.status().to_string();
  return ev.ok() ? ev->error_rel_max_disp : 1.0;
}

}  // namespace hc::material::testing
