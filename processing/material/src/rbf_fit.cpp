#include "processing/material/rbf_fit.h"

#include <fmt/format.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace hc::material {

Status RbfFitOptions::validate() const {
  if (!(tolerance >= 0) || !std::isfinite(tolerance))
    return invalid_argument("tolerance: must be >= 0");
  if (max_basis < 1) return invalid_argument("max_basis: must be >= 1");
  if (!(small_strain_fraction > 0 && small_strain_fraction <= 1))
    return invalid_argument("small_strain_fraction: must be in (0, 1]");
  if (!(lambda_floor_fraction > 0 && lambda_floor_fraction <= 1))
    return invalid_argument("lambda_floor_fraction: must be in (0, 1]");
  if (!(max_poisson > 0 && max_poisson < 0.5))
    return invalid_argument("max_poisson: must be in (0, 0.5)");
  return {};
}

void solve_rbf_weights(const std::vector<Vector6d>& centres, const std::vector<Vector6d>& strains,
                       const std::vector<Eigen::Vector2d>& params, StrainRbf* rbf) {
  const auto n = static_cast<Eigen::Index>(strains.size());
  const auto m = static_cast<Eigen::Index>(centres.size());
  Eigen::MatrixXd a(n, m + 1);
  Eigen::MatrixXd b(n, 2);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Vector6d& e = strains[static_cast<std::size_t>(k)];
    for (Eigen::Index i = 0; i < m; ++i)
      a(k, i) = (e - centres[static_cast<std::size_t>(i)]).norm();
    a(k, m) = 1.0;
    b.row(k) = params[static_cast<std::size_t>(k)].transpose();
  }
  // Column scaling keeps the kernel columns (~strain magnitudes, 1e-3..1) and the constant column
  // comparable for the rank decision.
  Eigen::VectorXd scale = a.colwise().norm().transpose();
  for (Eigen::Index i = 0; i < scale.size(); ++i) scale(i) = scale(i) > 0 ? scale(i) : 1.0;
  const Eigen::MatrixXd as = a * scale.cwiseInverse().asDiagonal();
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(as);
  cod.setThreshold(1e-10);
  Eigen::MatrixXd x = cod.solve(b);
  x = scale.cwiseInverse().asDiagonal() * x;
  rbf->centres = centres;
  rbf->weights = x.topRows(m);
  rbf->constant = x.row(m).transpose();
}

Result<StrainRbf> fit_strain_rbf(const std::vector<Vector6d>& strains,
                                 const std::vector<Eigen::Vector2d>& params,
                                 const RbfFitOptions& options, RbfFitSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  if (strains.empty()) return invalid_argument("fit_strain_rbf: no examples");
  if (strains.size() != params.size())
    return invalid_argument(fmt::format("fit_strain_rbf: {} strains but {} parameter vectors",
                                        strains.size(), params.size()));
  for (std::size_t k = 0; k < strains.size(); ++k) {
    if (!strains[k].allFinite() || !params[k].allFinite())
      return invalid_argument(fmt::format("fit_strain_rbf: example {} is not finite", k));
    if (!(params[k](0) > 0))
      return invalid_argument(fmt::format("fit_strain_rbf: example {} has lambda <= 0", k));
  }
  const std::size_t n = strains.size();

  // Zero-strain pseudo-example: mean parameters of the smallest-strain examples.
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return strains[a].norm() < strains[b].norm(); });
  const std::size_t n_small = std::max<std::size_t>(
      1,
      static_cast<std::size_t>(std::floor(options.small_strain_fraction * static_cast<double>(n))));
  Eigen::Vector2d small_mean = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n_small; ++i) small_mean += params[order[i]];
  small_mean /= static_cast<double>(n_small);

  // Data for the least squares: all examples plus the zero-strain pseudo-example.
  std::vector<Vector6d> data_strains = strains;
  std::vector<Eigen::Vector2d> data_params = params;
  data_strains.push_back(Vector6d::Zero());
  data_params.push_back(small_mean);

  double min_lambda = params[0](0);
  for (const auto& p : params) min_lambda = std::min(min_lambda, p(0));

  StrainRbf rbf;
  rbf.lambda_floor_pa = options.lambda_floor_fraction * min_lambda;
  rbf.max_poisson = options.max_poisson;
  std::vector<Vector6d> centres = {Vector6d::Zero()};
  std::vector<char> in_basis(n, 0);
  std::vector<int> chosen = {-1};
  double max_err = 0, rms_err = 0;
  while (true) {
    solve_rbf_weights(centres, data_strains, data_params, &rbf);
    max_err = 0;
    rms_err = 0;
    std::size_t worst = n;
    double worst_err = -1;
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector2d d = rbf.evaluate_raw(strains[k]) - params[k];
      const double err = d.cwiseAbs().maxCoeff() / params[k](0);
      max_err = std::max(max_err, err);
      rms_err += err * err;
      if (!in_basis[k] && err > worst_err) {
        worst_err = err;
        worst = k;
      }
    }
    rms_err = std::sqrt(rms_err / static_cast<double>(n));
    if (max_err <= options.tolerance || static_cast<int>(centres.size()) >= options.max_basis ||
        worst == n)
      break;
    in_basis[worst] = 1;
    centres.push_back(strains[worst]);
    chosen.push_back(static_cast<int>(worst));
  }
  if (summary) {
    summary->basis_size = static_cast<int>(centres.size());
    summary->max_error = max_err;
    summary->rms_error = rms_err;
    summary->chosen = std::move(chosen);
  }
  return rbf;
}

}  // namespace hc::material
