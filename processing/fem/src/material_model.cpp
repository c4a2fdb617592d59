#include "processing/fem/material_model.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace hc::fem {

LambdaAlpha lambda_alpha_from_youngs_poisson(double youngs_pa, double poisson) {
  const double lambda = youngs_pa / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
  return {lambda, lambda * poisson};
}

YoungsPoisson youngs_poisson_from_lambda_alpha(const LambdaAlpha& p) {
  const double nu = p.alpha / p.lambda;
  return {p.lambda * (1.0 + nu) * (1.0 - 2.0 * nu), nu};
}

Status validate_youngs_poisson(double youngs_pa, double poisson) {
  // Diamond, the stiffest bulk material, has E = 1.05e12 Pa; anything above is a typo, and values
  // near DBL_MAX overflow the stiffness matrix and the contact penalty (which scales with E).
  constexpr double kMaxYoungsPa = 1e13;
  if (!std::isfinite(youngs_pa) || youngs_pa <= 0 || youngs_pa > kMaxYoungsPa) {
    return invalid_argument(
        fmt::format("Young's modulus must be in (0, {:g}] Pa (diamond: 1.05e12 Pa), got {:g}",
                    kMaxYoungsPa, youngs_pa));
  }
  if (!std::isfinite(poisson) || poisson <= -1.0 || poisson >= 0.5) {
    return invalid_argument("Poisson's ratio must lie in (-1, 0.5), got " +
                            std::to_string(poisson));
  }
  return {};
}

bool is_physically_valid(const LambdaAlpha& p) {
  return std::isfinite(p.lambda) && std::isfinite(p.alpha) && p.lambda > 0 && p.alpha > -p.lambda &&
         p.alpha < 0.5 * p.lambda;
}

LambdaAlpha ConstantMaterial::params(Eigen::Index element, const Vector6d& /*strain*/) const {
  if (per_element_.empty()) return uniform_;
  return per_element_[static_cast<size_t>(element)];
}

Eigen::Index ConstantMaterial::num_elements() const {
  return per_element_.empty() ? -1 : static_cast<Eigen::Index>(per_element_.size());
}

LambdaAlpha LinearStrainMaterial::params(Eigen::Index /*element*/, const Vector6d& strain) const {
  LambdaAlpha p{p0_.lambda + dlambda_.dot(strain), p0_.alpha + dalpha_.dot(strain)};
  // Keep Poisson's ratio physically valid and Young's modulus above the floor (the clamp the thesis
  // applies during fitting, Sec. 4.6).
  const YoungsPoisson base = youngs_poisson_from_lambda_alpha(p0_);
  double nu = (p.lambda != 0) ? p.alpha / p.lambda : base.poisson;
  if (!std::isfinite(nu) || nu <= -0.99 || nu >= 0.499) nu = base.poisson;
  double e = p.lambda * (1.0 + nu) * (1.0 - 2.0 * nu);
  if (!std::isfinite(e) || e < min_youngs_pa_) e = min_youngs_pa_;
  return lambda_alpha_from_youngs_poisson(e, nu);
}

}  // namespace hc::fem
