// The thesis's noise study (Sec. 4.5) on blocks other than the shipped one (noise_study_test.cpp),
// with the same settings (γ = 0.01 σ², Poisson prior 0.1, basis 3, joint material fit at noise;
// γ 1e-8 and RBF tolerance 0.02 without): different layer stiffnesses, stiffening and thicknesses,
// box sizes and meshes of 300, 1,200 and 3,000 tets, 9 examples each from the neo-Hookean
// reference, fixed seeds. Thesis: 0.3 / 2.1 / 3.1 / 4.4 % of the max displacement "on average" at
// 0 / 10 / 20 / 30 % noise; here the mean over the three blocks must be no worse, each block
// within 1.25x (one noise draw varies: see noise_study_test.cpp). The three blocks take ~15 min in
// Release on 2 cores: CI's default run fits the 300-tet block (each level within 1.25x);
// HARDCOPY_LONG_TESTS=1 runs all three and checks the mean.
#include <gtest/gtest.h>

#include <cstdio>

#include "hyperelastic_reference.h"
#include "noise_study.h"
#include "processing/material/fit.h"
#include "sanitizer.h"

namespace hc::material {
namespace {

using testing::kNoise;
using testing::kThesis;

struct StudyBlock {
  const char* name;
  int nx, ny, nz;
  Eigen::Vector3d size;
  std::vector<hyperelastic::MaterialLayer> layers;
  double probe_radius_m;
  double max_force_n;
  std::uint64_t seed;
};

// E in Pa, ν, stiffening β per layer; none of these was used to choose any fit setting.
std::vector<StudyBlock> blocks() {
  return {{"300 tets, two layers",
           5,
           5,
           2,
           {0.05, 0.05, 0.02},
           {{0.0, 0.008, {200e3, 0.3, 2.0}}, {0.008, 0.02, {40e3, 0.4, 6.0}}},
           0.008,
           1.5,
           31},
          {"1,200 tets, three layers",
           10,
           5,
           4,
           {0.06, 0.03, 0.024},
           {{0.0, 0.006, {80e3, 0.35, 3.0}},
            {0.006, 0.016, {250e3, 0.25, 1.0}},
            {0.016, 0.024, {40e3, 0.3, 8.0}}},
           0.008,
           2.0,
           32},
          {"3,000 tets, three layers",
           10,
           10,
           5,
           {0.05, 0.05, 0.025},
           {{0.0, 0.005, {300e3, 0.3, 1.0}},
            {0.005, 0.017, {50e3, 0.4, 4.0}},
            {0.017, 0.025, {120e3, 0.3, 2.0}}},
           0.01,
           3.0,
           33}};
}

double fit_error(const Samples& clean, int k, std::uint64_t seed) {
  HeterogeneousFitSummary fs;
  const double error = testing::noise_study_error(clean, kNoise[k], seed, &fs);
  std::printf("  noise %2.0f %%: error %.2f %% (thesis %.1f %%), fit %.1f s (joint %.1f s, %s)\n",
              100 * kNoise[k], 100 * error, 100 * kThesis[k], fs.time_s, fs.joint_time_s,
              fs.joint.matrix_free ? "matrix-free" : "dense");
  return error;
}

TEST(NoiseStudyBlocks, MeanErrorsNoWorseThanTheThesis) {
  HC_SKIP_WHEN_SANITIZED("~10x slower: heterogeneous fits up to 3,000 tets");
  double sum[4] = {0, 0, 0, 0};
  std::vector<StudyBlock> all = blocks();
  if (!hc::testing::long_tests()) all.resize(1);
  for (const StudyBlock& b : all) {
    testing::HyperelasticReference ref;
    ref.mesh = testing::box_mesh(b.nx, b.ny, b.nz, b.size.x(), b.size.y(), b.size.z());
    ref.layers = b.layers;
    SynthOptions o;
    o.examples = 9;
    o.seed = b.seed;
    o.probe.shape = "sphere";
    o.probe.radius_m = b.probe_radius_m;
    o.max_force_n = b.max_force_n;
    o.fixed_nodes = testing::bottom_nodes(ref.mesh);
    Result<Samples> clean = synthesize_samples(ref.mesh, ref.simulator(), o);
    ASSERT_TRUE(clean.ok()) << b.name << ": " << clean.status().to_string();
    std::printf("%s (%ld tets):\n", b.name, static_cast<long>(ref.mesh.num_tets()));
    for (int k = 0; k < 4; ++k) {
      const double e = fit_error(*clean, k, b.seed);
      EXPECT_LE(e, 1.25 * kThesis[k]) << b.name << ", noise " << kNoise[k];
      sum[k] += e;
    }
  }
  for (int k = 0; k < 4; ++k) {
    const double mean = sum[k] / static_cast<double>(all.size());
    std::printf("noise %2.0f %%: mean %.2f %% (thesis %.1f %%)\n", 100 * kNoise[k], 100 * mean,
                100 * kThesis[k]);
    // The thesis's "on average" criterion needs the three blocks (HARDCOPY_LONG_TESTS=1; measured
    // passing in 893 s). One block is one draw: the 300-tet block gives 0.10 / 2.56 / 3.35 /
    // 4.00 % (dense LM, g++ 12 Release), within the 1.25x above.
    if (all.size() == blocks().size()) {
      EXPECT_LE(mean, kThesis[k]) << "noise " << kNoise[k];
    }
  }
}

}  // namespace
}  // namespace hc::material
