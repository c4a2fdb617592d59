// Thesis Sec. 4.5 noise study, CI size: a virtual block with three layers of user-defined
// non-linear materials (strain-stiffening neo-Hookean, processing/hyperelastic), examples from that
// reference model, Gaussian noise of 0/10/20/30 % of each example's max displacement on the
// measured positions; the fitted material simulates the (clean) examples. Thesis: L2 error 0.3
// %, 2.1 %, 3.1 %, 4.4 % of the max displacement "on average"; ours must be no worse (the mean
// over five noise streams, MeanErrorsNoWorseThanTheThesis). The fit at the thesis's foam scale is
// timed in tests/bench/bench_material_fit.cpp.
//
// Result (g++ 12 Release, mean over noise streams 2026, 7, 99, 1, 2): 0.10 / 1.92 / 2.89 / 3.73 %
// (thesis 0.3 / 2.1 / 3.1 / 4.4 %); on five streams not used to choose any weight (11-15):
// 1.79 / 2.49 / 3.19 %. How it got there, stage by stage:
//
// What limited the errors (profiled per stage: per-example LM fit, the per-example parameters
// simulated as a constant material ("oracle"), then the RBF material; was 0.80/3.50/3.93/4.45 %):
// * Noise-free, 0.80 % -> 0.10 %: NOT the model family, the RBF or the mesh. One of the 9 examples
//   had its uniform start fitted to nu = 0; the per-element LM works on logit(nu / nu_max), whose
//   derivative vanishes there, so all its elements stayed at nu ~ 0 (40 iterations, 1.9 % fit
//   error vs ~0.1 % for the others) and that example's parameters poisoned every element's RBF.
//   fit_example now starts inside [0.1, 0.9] nu_max. With it, the per-example fits reach ~0.1 % and
//   the RBF material reproduces them (0.10 %).
// * Noisy: the per-example parameters simulated directly are already as far from the clean
//   positions as the RBF material (e.g. 3.1 % vs 3.1 % at 10 %), so the RBF neither adds nor
//   averages out the error; it is the estimation of (lambda, alpha) from one noisy example.
//   Poisson's ratio is hardly identified by displacements: under noise the per-example nu ran to 0
//   or 0.48 (lambda then varies 20x for the same E) -> a weak prior on nu (ParameterFitOptions::
//   poisson_prior) fixes that (30 %: 4.52 -> 4.24 %). The Laplacian weight trades noise against
//   smoothing the layer jumps (150/60/30 kPa); gamma = 0.01 sigma^2 is near the best at every level
//   (10 %: gamma 1e-5..1e-3 gives 3.0..3.7 %). Freezing R_e at the fitted instead of the noisy
//   configuration changed < 0.1 %. A finer mesh helps at 10 % (6x6x4: 2.4 %) but not uniformly
//   (5x5x4: 2.3 / 4.0 / 8.0 %) and costs 5x the CI time.
// * The error measure: ours is the RMS node distance over all visible free nodes of all examples
//   divided by the largest displacement of all examples (the error_rel_max_disp); the
//   thesis's "L2 error ... on average ... of the maximum displacement" does not pin the averaging
//   down (a per-example mean of distances would be lower, a per-example relative RMS higher: 4.5 %
//   at 10 %); we keep the definition. The noise is the issue's: sigma = noise x the
//   example's max displacement on every coordinate of every measured node (interior ones too), i.e.
//   nodes far from the probe get noise far above their displacement; the thesis's "variance of 10
//   %" may mean noise relative to each displacement, which would be much milder.
// Result of the per-example pipeline: 0.10 / 3.13 / 3.70 / 4.24 %.
// * Where the noisy error really comes from: run the noisy-level settings (γ = 1e-4, basis 3,
//   prior) on CLEAN data and the error is still 2.86 % (γ 1e-5: 1.96 %, 1e-6: 1.10 %): it is mostly
//   BIAS of the per-example Laplacian, on ln λ (scaling the ν channel's weight 0.1x..10x changed
//   nothing). Each example's effective λ field has a real bump under its probe where the material
//   stiffens, and the weight the noise needs flattens it. (The RBF basis size is not it: 12 gives
//   2.78 %.)
// * What worked: fit_joint_material (fit.h; HeterogeneousFitOptions::joint, `fit heterogeneous
//   --joint`), an extension of the thesis's method: after the per-example fits, ONE material fitted
//   to all examples at once - per tet λ0, ν and a stiffening k of a one-centre RBF, λ = λ0 (1 + k
//   ‖ε‖/ε_ref) - with the Laplacian on the material (ln λ0, logit ν, k) rather than on each
//   example's parameters, weight 0.03 γ summed over the examples, 2 passes of strain updates:
//   10 % 2.36 %, 20 % 3.51 %, 30 % 4.35 % (seed 2026); noise seed 7: 2.81 / 4.22 / 4.15 %
//   (per-example pipeline 3.23 / 4.70 / 6.24 %), seed 99: 2.52 / 4.03 / 5.33 % (3.19 / 4.14 /
//   5.42 %). Better at every noisy level but one (2026 at 30 %: 4.35 vs 4.24 %), still not the
//   thesis's 2.1 / 3.1 % - nor its 4.4 % at 30 % on every seed. Model bias of the one-centre
//   stiffening: 1.49 % on clean data at the same γ, 1.06 % at γ → 0 (the reference stiffens
//   quartically in energy, the RBF kernel is linear in ‖ε‖).
// * Tried and dropped: (a) keeping the greedy RBF and fitting only a per-tet scale of it (λ and ν)
//   to all examples: 3.13 -> 2.77 % at 10 % (its noisy shape stays); (b) a Huber (edge-preserving)
//   loss on the Laplacian rows, per example or joint: much worse (per example 8-20 %: with 576
//   unknowns and 300 measurements it lets the noise through; joint 2.96-4.2 %); (c) separate
//   stiffening of λ and α (4 unknowns per tet): 2.58 / 3.85 / 4.53 % (more variance); (d) a weaker
//   weight on k (0.1x) gives 2.33 / 3.24 / 3.60 % but only when the LM is stopped at 20
//   iterations per pass; converged it is 2.62 / 3.64 / 3.88 %, so that was early stopping, not
//   kept; (e) more strain-update passes (4): no change; (f) smaller per-example γ before the joint
//   fit: worse; (g) joint weight 0.01 / 0.1 (instead of 0.03) x γ: 2.52 / 3.89 / 4.49 and
//   2.63 / 3.56 / 3.96 % (seed 2026), seeds 7 and 99 likewise no better overall. Noise-aware
//   weighting (brief idea 2) is already in place: residuals are divided by each example's s, which
//   is the noise's σ / noise level, i.e. the Gaussian maximum likelihood.
// * Quadratic-like stiffening (JointRefinementOptions::quadratic_stiffening, default on): a 4th
//   parameter m per tet, λ = λ0 (1 + k ‖ε‖/ε_ref + m h(ε)) with h ≈ ‖ε‖²/ε_ref² built from 12 more
//   RBF centres ±ε_ref e_k (fit.h), same format. Model bias on CLEAN data at γ_J → 0 (1e-5 x):
//   1.03-1.08 % -> 0.85-0.96 %; at the noisy levels' γ: 1.78 / 2.39 / 2.85 % -> 1.54 / 2.23 /
//   2.72 %. Noise study (joint LM function tolerance 1e-5, which leaves the errors within 0.02 %
//   of the converged ones): seed 2026 2.36 / 3.32 / 3.91 %, seed 7 2.60 / 4.17 / 4.17 %, seed 99
//   2.38 / 4.06 / 5.28 % (linear k only: 2.36 / 3.51 / 4.35, 2.81 / 4.22 / 4.15, 2.52 / 4.03 /
//   5.33 %): mean of the 9 noisy cells 3.70 -> 3.58 %, two cells +0.02 / +0.03 %. κ 0.3x / 3x and
//   γ_J 0.015 / 0.05 (instead of 0.03) x γ, 1 or 3 strain passes (instead of 2): no better. 10 %
//   stays at ~2.4 %: at that level even clean data give 1.54 %, i.e. the smoothing the noise needs,
//   not the model, now dominates.
// * Rotations re-frozen at the model's configuration between the joint passes (fit.h; the first
//   pass still linearises at the noisy measured one): seed 2026 2.36 / 3.32 / 3.91 -> 2.26 /
//   3.09 / 3.55 %; over the noise seeds 2026, 7, 99, 1, 2 the means went 2.31 / 3.73 / 4.58 ->
//   2.21 / 3.35 / 4.04 % (per seed 10 %: 2.26 2.42 2.28 1.88 2.22; 20 %: 3.09 3.66 3.64 2.77
//   3.58; 30 %: 3.55 4.18 3.87 3.75 4.85). With the re-freeze, 3 passes, or a re-freeze before
//   the first pass, or γ_J 0.015 / 0.06 x γ: no better on seeds 2026, 7, 1.
// * Tried and dropped after it (session 5): (h) a piecewise-constant material - the smooth fit's
//   parameters clustered by k-means into K <= 6 regions, refitted per region, K by BIC: 4.40 /
//   4.12 / 4.45 % (seed 2026): the smooth fit blurs the layers too much for the clusters to find
//   them; even the TRUE three layers as regions (an oracle, 12 parameters) gave 1.80 / 4.52 /
//   3.78 % (seed 7: 1.74 / 3.20 / 7.29 %), i.e. the stiffness-vs-stiffening trade-off of the
//   soft top layer is poorly determined at 20-30 % noise even then; (i) 16 or 25 examples
//   instead of 9: 2.42 / 3.90 / 5.25 and 2.20 / 3.54 / 5.09 % (seed 2026), no better, and the
//   clean error rises to 0.23 / 0.39 % (probes nearer the edges strain the mesh harder).
// * The joint material's Laplacian over FACE neighbours instead of the thesis's vertex
//   neighbours (JointRefinementOptions::adjacency, session 6). With 6 tets per cube a tet has
//   ~20-40 vertex neighbours, reaching across a whole 10 mm layer of this block from every tet, so
//   the weight the noise needs blurs both layer jumps; a face neighbour stencil (≤ 4) smooths
//   within a layer at a far heavier weight and penalises a jump only across the faces on it. The
//   weights were chosen on streams 2026, 7, 99, 1, 2 (fit.h: γ_J 30 x γ, κ 30; means 2.21 / 3.35
//   / 4.04 % -> 1.92 / 2.89 / 3.73 %) and checked on streams 11-15, not used for the choice:
//   vertex stencil (0.03, κ 1) 2.11 / 3.08 / 3.76 %, face stencil 1.79 / 2.49 / 3.19 %, better on
//   every stream at every level (per stream 10 %: 2.06 -> 1.72, 2.17 -> 1.91, 2.01 -> 1.81,
//   2.12 -> 1.70, 2.17 -> 1.83).
// * Not tried: γ chosen from the data (GCV / discrepancy principle) per noise draw.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>

#include "hyperelastic_reference.h"
#include "noise_study.h"
#include "processing/material/fit.h"
#include "sanitizer.h"


namespace hc::material {
namespace {

constexpr int kExamples = 9;

testing::HyperelasticReference three_layers() {
  testing::HyperelasticReference ref;
  ref.mesh = testing::box_mesh(4, 4, 3, 0.04, 0.04, 0.03);
  // Soft, stiffening top; medium middle; stiff bottom (E in Pa, nu, stiffening beta).
  ref.layers = {{0.0, 0.01, {150e3, 0.3, 1.0}},
                {0.01, 0.02, {60e3, 0.35, 4.0}},
                {0.02, 0.03, {30e3, 0.25, 8.0}}};
  return ref;
}

SynthOptions synth_options(const testing::HyperelasticReference& ref, int examples, double noise) {
  SynthOptions o;
  o.examples = examples;
  o.noise = noise;
  o.seed = 2026;
  o.probe.shape = "sphere";
  o.probe.radius_m = 0.01;
  o.max_force_n = 3.0;
  o.fixed_nodes = testing::bottom_nodes(ref.mesh);
  return o;
}

using testing::kNoise;
using testing::kThesis;

// error_rel_max_disp of the material fitted to the examples with noise level kNoise[k] (noise
// stream `seed`), evaluated on the clean examples.
double noise_study_error(const Samples& clean, int k, std::uint64_t seed) {
  HeterogeneousFitSummary fs;
  const double error = testing::noise_study_error(clean, kNoise[k], seed, &fs);
  std::printf(
      "noise %2.0f %% (seed %llu): error %.2f %% of max displacement (thesis %.1f %%), basis "
      "%.2f, fit rms %.2f %%, fit %.1f s (per example %.1f s, joint %.1f s, %d LM iterations)\n",
      100 * kNoise[k], static_cast<unsigned long long>(seed), 100 * error, 100 * kThesis[k],
      fs.mean_basis_size, 100 * fs.rms_error_m / clean.max_displacement_m(), fs.time_s,
      fs.parameter_time_s, fs.joint_time_s, fs.joint.iterations);
  return error;
}

Samples clean_examples() {
  const testing::HyperelasticReference ref = three_layers();
  Result<Samples> clean =
      synthesize_samples(ref.mesh, ref.simulator(), synth_options(ref, kExamples, 0));
  EXPECT_TRUE(clean.ok()) << clean.status().to_string();
  return clean.ok() ? *clean : Samples{};
}

// Regression bounds for one noise stream (HC_NOISE_SEED, default 2026): what this implementation
// reaches today (measured 0.11 %, 2.03 %, 3.60 %, 4.24 % with g++ 12 Release, dense LM, the
// reference on surface points; 0.10 / 1.89 / 3.13 / 4.02 % with node contact before) with a ~10 % margin for
// other compilers' rounding; the noise-free bound is the thesis's 0.3 %.
TEST(NoiseStudy, ErrorsWithinMeasuredBounds) {
  HC_SKIP_WHEN_SANITIZED("~8 min: 9 examples fitted per noise level");
  const Samples clean = clean_examples();
  ASSERT_GT(clean.examples.size(), 0u);
  const char* seed_env = std::getenv("HC_NOISE_SEED");
  const std::uint64_t seed = seed_env ? std::strtoull(seed_env, nullptr, 10) : 2026;
  const double bound[] = {0.003, 0.022, 0.040, 0.047};
  for (int k = 0; k < 4; ++k)
    EXPECT_LE(noise_study_error(clean, k, seed), bound[k]) << "noise " << kNoise[k];
}

// The acceptance criterion, thesis Sec. 4.5: "on average" no worse than 0.3 %, 2.1 %,
// 3.1 %, 4.4 %. One noise draw varies a lot, so the criterion is the mean over five noise
// streams. With the reference indentation on the specimen's surface points (issue 13; dense LM,
// g++ 12 Release): means 0.11 / 1.86 / 2.75 / 3.27 %, single streams 1.64-2.03 / 2.22-3.60 /
// 2.40-4.24 %. Before, with node contact in the reference: means 0.10 / 1.92 / 2.89 / 3.73 %.
// The streams are the ones the joint fit's weights were chosen on (fit.h).
TEST(NoiseStudy, MeanErrorsNoWorseThanTheThesis) {
  HC_SKIP_WHEN_SANITIZED("~25 min: 16 fits of 9 examples");
  const Samples clean = clean_examples();
  ASSERT_GT(clean.examples.size(), 0u);
  EXPECT_LE(noise_study_error(clean, 0, 2026), kThesis[0]);  // no noise: one run is the mean
  const std::uint64_t seeds[] = {2026, 7, 99, 1, 2};
  for (int k = 1; k < 4; ++k) {
    double sum = 0;
    for (const std::uint64_t seed : seeds) {
      const double e = noise_study_error(clean, k, seed);
      sum += e;
    }
    const double mean = sum / static_cast<double>(std::size(seeds));
    std::printf("noise %2.0f %%: mean error %.2f %% (thesis %.1f %%)\n", 100 * kNoise[k],
                100 * mean, 100 * kThesis[k]);
    EXPECT_LE(mean, kThesis[k]) << "noise " << kNoise[k];
  }
}

}  // namespace
}  // namespace hc::material
