// Greedy strain-space basis selection and least-squares RBF weights for one element (thesis Sec.
// 4.3.2, after Carr et al. 2001): start with a centre at zero strain carrying the average of the
// small-strain examples' parameters, then repeatedly add the example with the largest error until
// every example is reproduced within a tolerance; after every addition the weights are the least-
// squares fit to ALL examples (Eq. 4.9 with a constant term, see material.h).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "common/status.h"
#include "processing/material/material.h"

namespace hc::material {

struct RbfFitOptions {
  // Stop when every example's error max(|Δλ|, |Δα|) / λ_example is at most this (dimensionless).
  double tolerance = 0.05;
  // Largest basis (including the zero-strain centre); ≥ 1.
  int max_basis = 12;
  // The examples whose strain norm is among the smallest `small_strain_fraction` of all (at least
  // one) give the zero-strain average.
  double small_strain_fraction = 0.25;
  // Written into the StrainRbf: λ floor = lambda_floor_fraction × smallest example λ.
  double lambda_floor_fraction = 0.05;
  double max_poisson = kDefaultMaxPoisson;

  Status validate() const;
};

struct RbfFitSummary {
  int basis_size = 0;       // centres, including the zero-strain one
  double max_error = 0;     // largest relative error over the examples at the end
  double rms_error = 0;     // RMS relative error
  std::vector<int> chosen;  // example indices added to the basis, in order (the zero centre is -1)
};

// `strains[k]` (6-vector, Eq. 4.1 order) and `params[k]` (λ, α in Pa, λ > 0) of example k. Fails
// with kInvalidArgument on mismatched sizes, no examples, or non-finite / non-positive λ inputs.
Result<StrainRbf> fit_strain_rbf(const std::vector<Vector6d>& strains,
                                 const std::vector<Eigen::Vector2d>& params,
                                 const RbfFitOptions& options, RbfFitSummary* summary = nullptr);

// Least-squares weights and constant for a fixed set of centres over the data (minimum-norm when
// rank-deficient). Used by fit_strain_rbf; exposed for tests.
void solve_rbf_weights(const std::vector<Vector6d>& centres, const std::vector<Vector6d>& strains,
                       const std::vector<Eigen::Vector2d>& params, StrainRbf* rbf);

}  // namespace hc::material
