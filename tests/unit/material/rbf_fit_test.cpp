// Greedy RBF basis selection (thesis Sec. 4.3.2, Carr et al. 2001) on analytic functions.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "processing/material/rbf_fit.h"

namespace hc::material {
namespace {

std::vector<Vector6d> random_strains(int n, double scale, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  std::vector<Vector6d> out;
  for (int k = 0; k < n; ++k) {
    Vector6d e;
    for (int i = 0; i < 6; ++i) e(i) = u(rng);
    out.push_back(e);
  }
  return out;
}

// Strains along `directions` load paths (unit directions in strain space) at `steps` magnitudes up
// to max_norm, as monotonic probing produces them, plus a few elements that barely deform.
std::vector<Vector6d> load_path_strains(int directions, int steps, double max_norm, unsigned seed) {
  std::vector<Vector6d> out;
  for (const Vector6d& d : random_strains(directions, 1.0, seed))
    for (int s = 1; s <= steps; ++s) out.push_back(d.normalized() * max_norm * s / steps);
  for (const Vector6d& d : random_strains(3, 1e-6, seed + 1)) out.push_back(d);
  return out;
}

TEST(RbfFit, RadialFunctionIsExactWithTheZeroCentreAlone) {
  // p(eps) = c + w |eps| lies in the span of {phi(|eps - 0|), 1}: one centre must reproduce it.
  const auto strains = load_path_strains(4, 6, 0.2, 1);
  std::vector<Eigen::Vector2d> params;
  for (const auto& e : strains) params.emplace_back(1e5 + 4e5 * e.norm(), 3e4 + 5e4 * e.norm());
  RbfFitOptions options;
  options.tolerance = 1e-5;
  options.max_basis = 1;
  options.small_strain_fraction = 0.1;
  RbfFitSummary summary;
  Result<StrainRbf> rbf = fit_strain_rbf(strains, params, options, &summary);
  ASSERT_TRUE(rbf.ok()) << rbf.status().to_string();
  // The zero-strain pseudo-sample averages the three near-zero strains (|eps| ~ 1e-6), so it lies
  // on the function to ~4e5 * 1e-6 / 1e5 = 4e-6 relative.
  EXPECT_EQ(summary.basis_size, 1);
  EXPECT_LE(summary.max_error, 1e-5);
  const Vector6d probe = random_strains(1, 0.2, 99)[0];
  EXPECT_NEAR(rbf->evaluate_raw(probe)(0), 1e5 + 4e5 * probe.norm(), 1e-3 * 1e5);
}

TEST(RbfFit, InterpolatesAllSamplesWhenEveryExampleIsACentre) {
  // Smooth non-radial function; with tolerance 0 and no basis limit the RBF interpolates.
  const auto strains = random_strains(25, 0.1, 2);
  std::vector<Eigen::Vector2d> params;
  const auto f = [](const Vector6d& e) {
    return Eigen::Vector2d(2e5 * (1 + 30 * e(0) * e(0) + 2 * e(1) + std::sin(5 * e(3))),
                           5e4 * (1 + 10 * e(2) * e(2)));
  };
  for (const auto& e : strains) params.push_back(f(e));
  RbfFitOptions options;
  options.tolerance = 0;
  options.max_basis = 100;
  RbfFitSummary summary;
  Result<StrainRbf> rbf = fit_strain_rbf(strains, params, options, &summary);
  ASSERT_TRUE(rbf.ok());
  EXPECT_EQ(summary.basis_size, 26);
  for (std::size_t k = 0; k < strains.size(); ++k) {
    EXPECT_NEAR(rbf->evaluate_raw(strains[k])(0), params[k](0), 1e-6 * params[k](0));
    EXPECT_NEAR(rbf->evaluate_raw(strains[k])(1), params[k](1), 1e-6 * params[k](1));
  }
}

TEST(RbfFit, GreedySelectionMeetsToleranceWithFewCentresAndGeneralises) {
  // A stiffening material: lambda grows with the volumetric and deviatoric strain magnitudes.
  const auto strains = load_path_strains(6, 8, 0.15, 3);
  const auto f = [](const Vector6d& e) {
    const double s = e.norm();
    return Eigen::Vector2d(1e5 * (1 + 3 * s + 8 * s * s), 3e4 * (1 + 3 * s + 8 * s * s));
  };
  std::vector<Eigen::Vector2d> params;
  for (const auto& e : strains) params.push_back(f(e));
  RbfFitOptions options;
  options.tolerance = 0.01;
  options.max_basis = 48;
  RbfFitSummary summary;
  Result<StrainRbf> rbf = fit_strain_rbf(strains, params, options, &summary);
  ASSERT_TRUE(rbf.ok());
  EXPECT_LE(summary.max_error, 0.01);
  EXPECT_LT(summary.basis_size, 20);  // far fewer centres than examples
  ASSERT_EQ(summary.chosen.size(), static_cast<std::size_t>(summary.basis_size));
  EXPECT_EQ(summary.chosen[0], -1);
  // Held-out strains between the samples of the load paths: within a few per cent.
  for (const Vector6d& d : random_strains(6, 1.0, 3))
    for (double s : {0.01, 0.05, 0.0925, 0.14}) {
      const Vector6d e = d.normalized() * s;
      EXPECT_NEAR(rbf->evaluate_raw(e)(0), f(e)(0), 0.03 * f(e)(0)) << s;
    }
}

TEST(RbfFit, ErrorDecreasesAsTheBasisGrows) {
  const auto strains = load_path_strains(5, 8, 0.1, 5);
  std::vector<Eigen::Vector2d> params;
  for (const auto& e : strains)
    params.emplace_back(1e5 * std::exp(5 * e(0) - 3 * e(2)), 2e4 * std::exp(2 * e(1)));
  double previous = 1e300;
  for (int m : {1, 3, 6, 12, 24}) {
    RbfFitOptions options;
    options.tolerance = 0;
    options.max_basis = m;
    RbfFitSummary summary;
    ASSERT_TRUE(fit_strain_rbf(strains, params, options, &summary).ok());
    EXPECT_LE(summary.rms_error, previous * (1 + 1e-9)) << m;
    previous = summary.rms_error;
  }
  EXPECT_LT(previous, 0.01);
}

TEST(RbfFit, BadInputIsRefused) {
  std::vector<Vector6d> s = {Vector6d::Zero()};
  std::vector<Eigen::Vector2d> p = {Eigen::Vector2d(-1, 0)};
  EXPECT_FALSE(fit_strain_rbf(s, p, {}).ok());
  p[0] = Eigen::Vector2d(std::nan(""), 0);
  EXPECT_FALSE(fit_strain_rbf(s, p, {}).ok());
  EXPECT_FALSE(fit_strain_rbf({}, {}, {}).ok());
  p.push_back(Eigen::Vector2d(1, 0));
  EXPECT_FALSE(fit_strain_rbf(s, p, {}).ok());
  RbfFitOptions bad;
  bad.max_basis = 0;
  EXPECT_FALSE(bad.validate().ok());
}

}  // namespace
}  // namespace hc::material
